#pragma once
// A small command-line parser: --name value / --name=value / boolean --name, with --help text
// generated from the registrations. Unknown flags and bad values are errors naming the flag.
#include <functional>
#include <string>
#include <vector>

#include "vd/common/status.h"

namespace vd {

class FlagParser {
 public:
  explicit FlagParser(std::string usage) : usage_(std::move(usage)) {}
  void AddString(const std::string& name, std::string* value, const std::string& help);
  void AddInt(const std::string& name, int64_t* value, const std::string& help);
  void AddFloat(const std::string& name, double* value, const std::string& help);
  void AddBool(const std::string& name, bool* value, const std::string& help);
  // Parses argv; *help_requested is set for --help / -h (the caller prints Help() and exits 0).
  Status Parse(int argc, char** argv, bool* help_requested);
  std::string Help() const;

 private:
  struct Flag {
    std::string name, help, default_text;
    bool is_bool = false;
    std::function<Status(const std::string&)> set;
  };
  std::string usage_;
  std::vector<Flag> flags_;
};

}  // namespace vd
