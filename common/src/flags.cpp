#include "vd/common/flags.h"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace vd {
namespace {

std::string NumberText(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// A flag's help text indented under it, broken at spaces into lines of at most kHelpWidth.
constexpr size_t kHelpWidth = 100;
std::string Wrapped(const std::string& text) {
  const std::string indent = "      ";
  std::string out, line;
  std::istringstream words(text);
  std::string word;
  while (words >> word) {
    if (!line.empty() && indent.size() + line.size() + 1 + word.size() > kHelpWidth) {
      out += indent + line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  if (!line.empty()) out += indent + line + "\n";
  return out;
}

}  // namespace

StatusOr<double> ParseFlagNumber(const std::string& flag, const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || errno != 0 || end != text.c_str() + text.size() || !std::isfinite(v))
    return InvalidArgument("--" + flag + " expects a number, got '" + text + "'");
  return v;
}

StatusOr<int64_t> ParseFlagInteger(const std::string& flag, const std::string& text, int64_t lo, int64_t hi) {
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || errno != 0 || end != text.c_str() + text.size())
    return InvalidArgument("--" + flag + " expects an integer, got '" + text + "'");
  if (v < lo || v > hi) return InvalidArgument("--" + flag + " = " + text + " is out of range");
  return int64_t(v);
}

Status ParamOutOfBounds(const std::string& owner, const std::string& field, double value, const std::string& bound) {
  return InvalidArgument(owner + "." + field + " = " + NumberText(value) + " violates " + bound);
}

FlagParser::FlagParser(std::string usage, std::string epilogue)
    : usage_(std::move(usage)), epilogue_(std::move(epilogue)) {}

void FlagParser::Section(const std::string& title) { section_ = title; }

void FlagParser::Register(Flag flag) {
  flag.section = section_;
  if (flag.kind == Kind::kValue && flag.metavar.empty()) flag.metavar = "VALUE";
  flags_.push_back(std::move(flag));
}

void FlagParser::Add(const std::string& name, std::string* value, const std::string& help, const std::string& metavar) {
  Register({name, metavar, help, *value, "", Kind::kValue, [value](const std::string& v) {
              *value = v;
              return Status::Ok();
            }});
}

void FlagParser::Add(const std::string& name, int* value, const std::string& help, const std::string& metavar) {
  Register({name, metavar, help, std::to_string(*value), "", Kind::kValue, [value, name](const std::string& v) {
              VD_ASSIGN_OR_RETURN(int64_t x, ParseFlagInteger(name, v, INT_MIN, INT_MAX));
              *value = int(x);
              return Status::Ok();
            }});
}

void FlagParser::Add(const std::string& name, int64_t* value, const std::string& help, const std::string& metavar) {
  Register({name, metavar, help, std::to_string(*value), "", Kind::kValue, [value, name](const std::string& v) {
              VD_ASSIGN_OR_RETURN(*value, ParseFlagInteger(name, v));
              return Status::Ok();
            }});
}

void FlagParser::Add(const std::string& name, float* value, const std::string& help, const std::string& metavar) {
  Register({name, metavar, help, NumberText(*value), "", Kind::kValue, [value, name](const std::string& v) {
              VD_ASSIGN_OR_RETURN(double x, ParseFlagNumber(name, v));
              if (std::abs(x) > 3.4e38) return InvalidArgument("--" + name + " = " + v + " is out of range");
              *value = float(x);
              return Status::Ok();
            }});
}

void FlagParser::Add(const std::string& name, double* value, const std::string& help, const std::string& metavar) {
  Register({name, metavar, help, NumberText(*value), "", Kind::kValue, [value, name](const std::string& v) {
              VD_ASSIGN_OR_RETURN(*value, ParseFlagNumber(name, v));
              return Status::Ok();
            }});
}

void FlagParser::AddSwitch(const std::string& name, bool* value, const std::string& help) {
  Register({name, "", help, "", "", Kind::kSwitch, [value](const std::string&) {
              *value = true;
              return Status::Ok();
            }});
}

void FlagParser::AddNegation(const std::string& name, bool* value, const std::string& help) {
  Register({name, "", help, "", "", Kind::kSwitch, [value](const std::string&) {
              *value = false;
              return Status::Ok();
            }});
}

void FlagParser::AddCustom(const std::string& name, const std::string& metavar, const std::string& default_text,
                           const std::string& help, std::function<Status(const std::string&)> set) {
  Register({name, metavar, help, default_text, "", Kind::kValue, std::move(set)});
}

Status FlagParser::Parse(int argc, char** argv, bool* help_requested) {
  std::vector<std::string> args;
  for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
  return Parse(args, help_requested);
}

Status FlagParser::Parse(const std::vector<std::string>& args, bool* help_requested) {
  *help_requested = false;
  given_.clear();
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--help" || arg == "-h") {
      *help_requested = true;
      return Status::Ok();
    }
    if (arg.rfind("--", 0) != 0 || arg.size() == 2) return InvalidArgument("unexpected argument '" + arg + "' (see --help)");
    std::string name = arg.substr(2), value;
    bool inline_value = false;
    if (const size_t eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
      inline_value = true;
    }
    auto it = std::find_if(flags_.begin(), flags_.end(), [&](const Flag& f) { return f.name == name; });
    if (it == flags_.end()) return InvalidArgument("unknown flag --" + name + " (see --help)");
    if (it->kind == Kind::kSwitch) {
      if (inline_value) return InvalidArgument("--" + name + " takes no value");
    } else if (!inline_value) {
      if (i + 1 >= args.size()) return InvalidArgument("--" + name + " needs a value");
      value = args[++i];
    }
    VD_RETURN_IF_ERROR(it->set(value));
    given_.insert(name);
  }
  return Status::Ok();
}

std::optional<int> FlagParser::ParseCommandLine(int argc, char** argv, const std::string& program,
                                                const std::function<Status()>& validate) {
  bool help = false;
  Status s = Parse(argc, argv, &help);
  if (help) {
    std::fputs(Help().c_str(), stdout);
    return 0;
  }
  if (s.ok() && validate) s = validate();
  if (!s.ok()) {
    std::fprintf(stderr, "%s: %s\n", program.c_str(), s.message().c_str());
    return 2;
  }
  return std::nullopt;
}

std::string FlagParser::Help() const {
  std::ostringstream os;
  os << usage_ << "\n";
  std::string section = "\x01";
  for (const Flag& f : flags_) {
    if (f.section != section) {
      section = f.section;
      os << "\n" << (section.empty() ? "Flags" : section) << ":\n";
    }
    std::string text = f.help;
    if (f.kind == Kind::kValue && !f.default_text.empty()) text += " (default: " + f.default_text + ")";
    os << "  --" << f.name << (f.kind == Kind::kValue ? " " + f.metavar : "") << "\n" << Wrapped(text);
  }
  os << "  --help, -h\n      Show this text and exit.\n";
  if (!epilogue_.empty()) os << "\n" << epilogue_;
  return os.str();
}

}  // namespace vd
