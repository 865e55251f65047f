// Minimal JSON object writer for --json reports (flat keys, nested objects by prefix calls).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace facetree::cli {

class JsonWriter {
 public:
  JsonWriter() { open(); }
  void key(const std::string& name) {
    separator();
    out_ += quote(name) + ": ";
  }
  void field(const std::string& name, const std::string& value) { key(name), out_ += quote(value); }
  void field(const std::string& name, const char* value) { field(name, std::string(value)); }
  void field(const std::string& name, bool value) { key(name), out_ += value ? "true" : "false"; }
  void field(const std::string& name, uint64_t value) { key(name), out_ += std::to_string(value); }
  void field(const std::string& name, int64_t value) { key(name), out_ += std::to_string(value); }
  void field(const std::string& name, uint32_t value) { field(name, uint64_t{value}); }
  void field(const std::string& name, int value) { field(name, int64_t{value}); }
  void field(const std::string& name, double value) {
    key(name);
    if (!std::isfinite(value)) {
      out_ += "null";
      return;
    }
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%.9g", value);
    out_ += buffer;
  }
  void field(const std::string& name, const std::vector<double>& values) {
    key(name);
    out_ += "[";
    for (size_t i = 0; i < values.size(); ++i) {
      char buffer[32];
      std::snprintf(buffer, sizeof buffer, "%s%.9g", i ? ", " : "", values[i]);
      out_ += buffer;
    }
    out_ += "]";
  }
  void beginObject(const std::string& name) {
    key(name);
    open();
  }
  void endObject() {
    out_ += '\n';
    out_.append(2 * (depth_ - 1), ' ');
    out_ += '}';
    --depth_;
    first_ = false;
  }
  std::string finish() {
    while (depth_ > 0) endObject();
    return out_ + "\n";
  }

 private:
  void open() {
    out_ += "{";
    ++depth_;
    first_ = true;
  }
  void separator() {
    out_ += first_ ? "\n" : ",\n";
    out_.append(2 * depth_, ' ');
    first_ = false;
  }
  static std::string quote(const std::string& text) {
    std::string q = "\"";
    for (const char c : text) {
      if (c == '"' || c == '\\') {
        q += '\\';
        q += c;
      } else if (static_cast<unsigned char>(c) < 0x20) {
        char buffer[8];
        std::snprintf(buffer, sizeof buffer, "\\u%04x", c);
        q += buffer;
      } else {
        q += c;
      }
    }
    return q + "\"";
  }
  std::string out_;
  int depth_ = 0;
  bool first_ = true;
};

}  // namespace facetree::cli
