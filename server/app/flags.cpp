#include "flags.h"

#include <algorithm>
#include <sstream>

namespace vd {

void FlagParser::AddString(const std::string& name, std::string* value, const std::string& help) {
  flags_.push_back({name, help, value->empty() ? "" : *value, false, [value](const std::string& v) {
                      *value = v;
                      return Status::Ok();
                    }});
}

void FlagParser::AddInt(const std::string& name, int64_t* value, const std::string& help) {
  flags_.push_back({name, help, std::to_string(*value), false, [value, name](const std::string& v) {
                      try {
                        size_t used = 0;
                        *value = std::stoll(v, &used);
                        if (used == v.size()) return Status::Ok();
                      } catch (const std::exception&) {
                      }
                      return InvalidArgument("--" + name + " expects an integer, got '" + v + "'");
                    }});
}

void FlagParser::AddFloat(const std::string& name, double* value, const std::string& help) {
  std::ostringstream d;
  d << *value;
  flags_.push_back({name, help, d.str(), false, [value, name](const std::string& v) {
                      try {
                        size_t used = 0;
                        *value = std::stod(v, &used);
                        if (used == v.size()) return Status::Ok();
                      } catch (const std::exception&) {
                      }
                      return InvalidArgument("--" + name + " expects a number, got '" + v + "'");
                    }});
}

void FlagParser::AddBool(const std::string& name, bool* value, const std::string& help) {
  flags_.push_back({name, help, "", true, [value](const std::string&) {
                      *value = true;
                      return Status::Ok();
                    }});
}

Status FlagParser::Parse(int argc, char** argv, bool* help_requested) {
  *help_requested = false;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      *help_requested = true;
      return Status::Ok();
    }
    if (arg.rfind("--", 0) != 0) return InvalidArgument("unexpected argument '" + arg + "' (see --help)");
    std::string name = arg.substr(2), value;
    bool has_value = false;
    if (auto eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
      has_value = true;
    }
    auto it = std::find_if(flags_.begin(), flags_.end(), [&](const Flag& f) { return f.name == name; });
    if (it == flags_.end()) return InvalidArgument("unknown flag --" + name + " (see --help)");
    if (!it->is_bool && !has_value) {
      if (i + 1 >= argc) return InvalidArgument("--" + name + " needs a value");
      value = argv[++i];
    }
    VD_RETURN_IF_ERROR(it->set(value));
  }
  return Status::Ok();
}

std::string FlagParser::Help() const {
  std::ostringstream os;
  os << usage_ << "\n\nFlags:\n";
  for (const auto& f : flags_) {
    os << "  --" << f.name << (f.is_bool ? "" : " VALUE");
    os << "\n      " << f.help;
    if (!f.is_bool && !f.default_text.empty()) os << " (default: " << f.default_text << ")";
    os << "\n";
  }
  os << "  --help\n      Show this text.\n";
  return os.str();
}

}  // namespace vd
