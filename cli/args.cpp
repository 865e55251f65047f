// The command-line parser (args.h): options by name, values with k/M/G suffixes, usage errors.
#include "args.h"

#include <charconv>
#include <cmath>

namespace facetree::cli {

Args::Args(const std::vector<std::string>& argv, const std::set<std::string>& valued,
           const std::set<std::string>& flags, const std::map<std::string, std::string>& aliases) {
  for (size_t i = 0; i < argv.size(); ++i) {
    std::string arg = argv[i];
    if (arg.size() < 2 || arg[0] != '-') {
      positional_.push_back(arg);
      continue;
    }
    std::string inlineValue;
    bool hasInline = false;
    if (const size_t eq = arg.find('='); arg.rfind("--", 0) == 0 && eq != std::string::npos) {
      inlineValue = arg.substr(eq + 1);
      arg = arg.substr(0, eq);
      hasInline = true;
    }
    if (const auto alias = aliases.find(arg); alias != aliases.end()) arg = alias->second;
    if (arg.rfind("--", 0) != 0) throw UsageError("unknown option '" + arg + "'");
    const std::string name = arg.substr(2);
    if (valued.count(name)) {
      if (hasInline) {
        values_[name] = inlineValue;
      } else {
        if (i + 1 >= argv.size()) throw UsageError("option --" + name + " needs a value");
        values_[name] = argv[++i];
      }
    } else if (flags.count(name) && !hasInline) {
      flags_.insert(name);
    } else {
      throw UsageError("unknown option '" + argv[i] + "'");
    }
  }
}

std::optional<std::string> Args::value(const std::string& name) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return std::nullopt;
  return it->second;
}

std::string Args::valueOr(const std::string& name, const std::string& fallback) const {
  return value(name).value_or(fallback);
}

double Args::number(const std::string& name, double fallback) const {
  const auto text = value(name);
  if (!text) return fallback;
  double result = 0;
  const auto [end, error] = std::from_chars(text->data(), text->data() + text->size(), result);
  if (error != std::errc() || end != text->data() + text->size() || !std::isfinite(result))
    throw UsageError("option --" + name + " needs a number, got '" + *text + "'");
  return result;
}

uint64_t Args::count(const std::string& name, uint64_t fallback, bool binary) const {
  const auto text = value(name);
  if (!text) return fallback;
  uint64_t result = 0;
  const char* begin = text->data();
  const char* end = begin + text->size();
  const auto [stop, error] = std::from_chars(begin, end, result);
  uint64_t scale = 1;
  if (stop + 1 == end) {
    switch (*stop) {
      case 'k':
      case 'K':
        scale = binary ? uint64_t{1} << 10 : 1000;
        break;
      case 'm':
      case 'M':
        scale = binary ? uint64_t{1} << 20 : 1000000;
        break;
      case 'g':
      case 'G':
        scale = binary ? uint64_t{1} << 30 : 1000000000;
        break;
      default:
        scale = 0;
    }
  } else if (stop != end) {
    scale = 0;
  }
  if (error != std::errc() || scale == 0 || result > UINT64_MAX / scale)
    throw UsageError("option --" + name + " needs a whole number (suffix k, M or G allowed), got '" + *text +
                     "'");
  return result * scale;
}

}  // namespace facetree::cli
