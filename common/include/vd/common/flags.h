#pragma once
// The one command-line parser of every vdeform program: --name VALUE, --name=VALUE and switches,
// each flag bound to the field it sets. The field's current value is its default (one source:
// the struct's in-class initialiser), and --help is generated from the registrations. Unknown
// flags, missing values, values given to switches, malformed or non-finite numbers and integers
// out of the field's range are errors naming the flag.
#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "vd/common/status.h"

namespace vd {

class FlagParser {
 public:
  // usage: the text before the flags in --help; epilogue: after them (exit status, notes).
  explicit FlagParser(std::string usage, std::string epilogue = "");

  // Flags registered after this are listed under `title` in --help.
  void Section(const std::string& title);
  // metavar names the value in --help ("--save-dir DIR"); empty = "VALUE".
  void Add(const std::string& name, std::string* value, const std::string& help, const std::string& metavar = "");
  void Add(const std::string& name, int* value, const std::string& help, const std::string& metavar = "");
  void Add(const std::string& name, int64_t* value, const std::string& help, const std::string& metavar = "");
  void Add(const std::string& name, float* value, const std::string& help, const std::string& metavar = "");
  void Add(const std::string& name, double* value, const std::string& help, const std::string& metavar = "");
  // A switch: --name sets *value to true.
  void AddSwitch(const std::string& name, bool* value, const std::string& help);
  // A switch that turns something off: --name sets *value to false (--no-sift for features.enabled).
  void AddNegation(const std::string& name, bool* value, const std::string& help);
  // A value with its own syntax (codecs, WxH sizes, lists): `set` parses it into the field and
  // returns an error that says what was expected. default_text is shown in --help.
  void AddCustom(const std::string& name, const std::string& metavar, const std::string& default_text,
                 const std::string& help, std::function<Status(const std::string&)> set);

  // Parses argv[1..] (or args). *help_requested is set for --help / -h, which stops parsing (the
  // caller prints Help() and exits 0).
  Status Parse(int argc, char** argv, bool* help_requested);
  Status Parse(const std::vector<std::string>& args, bool* help_requested);
  // For main(): parses argv and then runs `validate` (the options' one check). Prints --help to
  // stdout and returns 0; prints "<program>: <error>" to stderr and returns 2 on bad arguments;
  // returns std::nullopt when the program should go on.
  std::optional<int> ParseCommandLine(int argc, char** argv, const std::string& program,
                                      const std::function<Status()>& validate = nullptr);
  // Whether --name appeared on the command line (to reject combinations that would be ignored).
  bool Given(const std::string& name) const { return given_.count(name) > 0; }
  std::string Help() const;

 private:
  enum class Kind { kValue, kSwitch };
  struct Flag {
    std::string name, metavar, help, default_text, section;
    Kind kind = Kind::kValue;
    std::function<Status(const std::string&)> set;
  };
  void Register(Flag flag);

  std::string usage_, epilogue_, section_;
  std::vector<Flag> flags_;
  std::set<std::string> given_;
};

// Parsers the bindings use, for custom flags too: the whole text must be a finite number / an
// integer in [lo, hi]; errors name the flag.
StatusOr<double> ParseFlagNumber(const std::string& flag, const std::string& text);
StatusOr<int64_t> ParseFlagInteger(const std::string& flag, const std::string& text, int64_t lo = INT64_MIN,
                                   int64_t hi = INT64_MAX);

// The parameter check every options struct's Validate() uses: "Owner.field = value violates bound".
Status ParamOutOfBounds(const std::string& owner, const std::string& field, double value, const std::string& bound);

}  // namespace vd
