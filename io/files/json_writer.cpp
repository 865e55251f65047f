// JsonWriter (facetree/io.h): the reports' JSON, one object at a time.
#include <cmath>
#include <cstdio>

#include "facetree/io.h"

namespace facetree {
namespace {

std::string quote(const std::string& text) {
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

}  // namespace

JsonWriter::JsonWriter() {
  open();
}

void JsonWriter::key(const std::string& name) {
  separator();
  out_ += quote(name) + ": ";
}

void JsonWriter::field(const std::string& name, const std::string& value) {
  key(name);
  out_ += quote(value);
}
void JsonWriter::field(const std::string& name, const char* value) {
  field(name, std::string(value));
}
void JsonWriter::field(const std::string& name, bool value) {
  key(name);
  out_ += value ? "true" : "false";
}
void JsonWriter::field(const std::string& name, uint64_t value) {
  key(name);
  out_ += std::to_string(value);
}
void JsonWriter::field(const std::string& name, int64_t value) {
  key(name);
  out_ += std::to_string(value);
}
void JsonWriter::field(const std::string& name, uint32_t value) {
  field(name, uint64_t{value});
}
void JsonWriter::field(const std::string& name, int value) {
  field(name, int64_t{value});
}
void JsonWriter::field(const std::string& name, double value) {
  key(name);
  if (!std::isfinite(value)) {
    out_ += "null";
    return;
  }
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.9g", value);
  out_ += buffer;
}
void JsonWriter::field(const std::string& name, const std::vector<double>& values) {
  key(name);
  out_ += "[";
  for (size_t i = 0; i < values.size(); ++i) {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%s%.9g", i ? ", " : "", values[i]);
    out_ += buffer;
  }
  out_ += "]";
}

void JsonWriter::beginObject(const std::string& name) {
  key(name);
  open();
}

void JsonWriter::endObject() {
  out_ += '\n';
  out_.append(2 * (depth_ - 1), ' ');
  out_ += '}';
  --depth_;
  first_ = false;
}

std::string JsonWriter::finish() {
  while (depth_ > 0) endObject();
  return out_ + "\n";
}

void JsonWriter::open() {
  out_ += "{";
  ++depth_;
  first_ = true;
}

void JsonWriter::separator() {
  out_ += first_ ? "\n" : ",\n";
  out_.append(2 * depth_, ' ');
  first_ = false;
}

}  // namespace facetree
