// A small command-line parser: positional arguments and --name value / --flag options, each
// command declaring what it accepts so unknown options are usage errors.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace facetree::cli {

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Args {
 public:
  // `valued` options take the next argument; `flags` take none. Short aliases map to long names.
  Args(const std::vector<std::string>& argv, const std::set<std::string>& valued,
       const std::set<std::string>& flags, const std::map<std::string, std::string>& aliases = {});
  const std::vector<std::string>& positional() const { return positional_; }
  bool flag(const std::string& name) const { return flags_.count(name) > 0; }
  std::optional<std::string> value(const std::string& name) const;
  std::string valueOr(const std::string& name, const std::string& fallback) const;
  double number(const std::string& name, double fallback) const;
  // A whole number with an optional suffix k, M or G: powers of 1024 when `binary` (sizes),
  // of 1000 otherwise (counts).
  uint64_t count(const std::string& name, uint64_t fallback, bool binary = false) const;

 private:
  std::vector<std::string> positional_;
  std::set<std::string> flags_;
  std::map<std::string, std::string> values_;
};

}  // namespace facetree::cli
