// The PLY header parser (ply_header.h): elements, properties and the checks that a header
// describes a triangle mesh this reader can stream.
#include "ply_header.h"

#include <array>
#include <charconv>
#include <string_view>

#include "read_error.h"
#include "text_tokens.h"
#include "vertex_store.h"

namespace facetree::stream_detail {
namespace {

struct ScalarName {
  std::string_view name;
  PlyScalar type;
};

constexpr std::array kScalarNames = {
    ScalarName{"char", PlyScalar::Int8},       ScalarName{"uchar", PlyScalar::UInt8},
    ScalarName{"short", PlyScalar::Int16},     ScalarName{"ushort", PlyScalar::UInt16},
    ScalarName{"int", PlyScalar::Int32},       ScalarName{"uint", PlyScalar::UInt32},
    ScalarName{"float", PlyScalar::Float32},   ScalarName{"double", PlyScalar::Float64},
    ScalarName{"int8", PlyScalar::Int8},       ScalarName{"uint8", PlyScalar::UInt8},
    ScalarName{"int16", PlyScalar::Int16},     ScalarName{"uint16", PlyScalar::UInt16},
    ScalarName{"int32", PlyScalar::Int32},     ScalarName{"uint32", PlyScalar::UInt32},
    ScalarName{"float32", PlyScalar::Float32}, ScalarName{"float64", PlyScalar::Float64},
};

constexpr std::string_view kCoordinateNames[3] = {"x", "y", "z"};
constexpr std::string_view kIndexListNames[2] = {"vertex_indices", "vertex_index"};

class HeaderParser {
 public:
  HeaderParser(InputBuffer& input, const std::string& name) : input_(input), name_(name) {}

  PlyHeader parse() {
    nextLine();  // "ply", checked by format detection
    bool sawFormat = false;
    for (;;) {
      if (!nextLine()) fail(line_ + 1, "unexpected end of file in header (missing end_header)");
      Tokens tokens(text_);
      const std::string_view keyword = tokens.next();
      if (keyword.empty() || keyword == "comment" || keyword == "obj_info") continue;
      if (keyword == "end_header") {
        if (!sawFormat) fail(line_, "missing format line");
        header_.lines = line_;
        check();
        return std::move(header_);
      }
      if (keyword == "format") {
        parseFormat(tokens);
        sawFormat = true;
      } else if (keyword == "element") {
        parseElement(tokens);
      } else if (keyword == "property") {
        parseProperty(tokens);
      } else {
        fail(line_, "unknown header keyword " + quoteToken(keyword));
      }
    }
  }

 private:
  [[noreturn]] void fail(uint64_t line, const std::string& reason) const {
    throwReadError(name_, Place::line(line), reason);
  }

  bool nextLine() { return input_.readLine(text_, line_, name_, "header line"); }

  void expectEnd(Tokens& tokens) const {
    const std::string_view extra = tokens.next();
    if (!extra.empty()) fail(line_, "unexpected " + quoteToken(extra) + " at end of header line");
  }

  void parseFormat(Tokens& tokens) {
    const std::string_view encoding = tokens.next();
    if (encoding == "ascii") {
      header_.encoding = PlyEncoding::Ascii;
    } else if (encoding == "binary_little_endian") {
      header_.encoding = PlyEncoding::BinaryLittleEndian;
    } else if (encoding == "binary_big_endian") {
      header_.encoding = PlyEncoding::BinaryBigEndian;
    } else {
      fail(line_, "unknown ply format " + quoteToken(encoding));
    }
    const std::string_view version = tokens.next();
    if (version != "1.0" && version != "1") fail(line_, "unsupported ply version " + quoteToken(version));
    expectEnd(tokens);
  }

  void parseElement(Tokens& tokens) {
    PlyElement element;
    element.name = std::string(tokens.next());
    element.line = line_;
    const std::string_view count = tokens.next();
    if (element.name.empty() || count.empty()) fail(line_, "element line needs a name and a count");
    const auto [end, error] = std::from_chars(count.data(), count.data() + count.size(), element.count);
    if (error != std::errc() || end != count.data() + count.size())
      fail(line_, "invalid element count " + quoteToken(count));
    expectEnd(tokens);
    header_.elements.push_back(std::move(element));
  }

  PlyScalar parseType(std::string_view name) const {
    for (const ScalarName& entry : kScalarNames)
      if (entry.name == name) return entry.type;
    fail(line_, "unknown property type " + quoteToken(name));
  }

  void parseProperty(Tokens& tokens) {
    if (header_.elements.empty()) fail(line_, "property before any element");
    PlyProperty property;
    std::string_view type = tokens.next();
    if (type == "list") {
      property.isList = true;
      property.countType = parseType(tokens.next());
      if (!isInteger(property.countType))
        fail(line_,
             std::string("list count type ") + scalarName(property.countType) + " is not an integer type");
      type = tokens.next();
    }
    property.type = parseType(type);
    property.name = std::string(tokens.next());
    if (property.name.empty()) fail(line_, "property line without a name");
    expectEnd(tokens);
    header_.elements.back().properties.push_back(std::move(property));
  }

  static int findProperty(const PlyElement& element, std::string_view name) {
    for (size_t i = 0; i < element.properties.size(); ++i)
      if (element.properties[i].name == name) return static_cast<int>(i);
    return -1;
  }

  // Roles and required properties; errors name the line of the offending element.
  void check() {
    uint64_t declaredFaces = 0;
    bool sawFaceElement = false;
    for (size_t e = 0; e < header_.elements.size(); ++e) {
      PlyElement& element = header_.elements[e];
      if (element.name == "vertex" && header_.vertexElement < 0) {
        element.role = PlyRole::Vertex;
        header_.vertexElement = static_cast<int>(e);
        for (int axis = 0; axis < 3; ++axis) {
          const int index = findProperty(element, kCoordinateNames[axis]);
          if (index < 0)
            fail(element.line, "vertex element has no property " + quoteToken(kCoordinateNames[axis]));
          if (element.properties[index].isList)
            fail(element.line, "vertex property " + quoteToken(kCoordinateNames[axis]) + " is a list");
          element.coordinate[axis] = index;
        }
      } else if (element.name == "face" || element.name == "tristrips") {
        element.role = element.name == "face" ? PlyRole::Face : PlyRole::TriStrips;
        sawFaceElement = true;
        for (const std::string_view candidate : kIndexListNames) {
          element.indexList = findProperty(element, candidate);
          if (element.indexList >= 0) break;
        }
        if (element.indexList < 0)
          fail(element.line, element.name + " element has no vertex_indices property");
        const PlyProperty& list = element.properties[element.indexList];
        if (!list.isList)
          fail(element.line, element.name + " property " + quoteToken(list.name) + " is not a list");
        if (!isInteger(list.type))
          fail(element.line, element.name + " property " + quoteToken(list.name) + " has non-integer type " +
                                 scalarName(list.type));
        declaredFaces += element.count;
      }
    }
    if (header_.vertexElement < 0) fail(line_, "no vertex element");
    if (!sawFaceElement) fail(line_, "no face element");
    if (declaredFaces == 0) fail(line_, "no faces");
  }

  InputBuffer& input_;
  const std::string& name_;
  PlyHeader header_;
  std::string_view text_;
  uint64_t line_ = 0;
};

}  // namespace

size_t scalarSize(PlyScalar type) {
  switch (type) {
    case PlyScalar::Int8:
    case PlyScalar::UInt8:
      return 1;
    case PlyScalar::Int16:
    case PlyScalar::UInt16:
      return 2;
    case PlyScalar::Int32:
    case PlyScalar::UInt32:
    case PlyScalar::Float32:
      return 4;
    case PlyScalar::Float64:
      return 8;
  }
  return 0;
}

bool isInteger(PlyScalar type) {
  return type != PlyScalar::Float32 && type != PlyScalar::Float64;
}

const char* scalarName(PlyScalar type) {
  switch (type) {
    case PlyScalar::Int8:
      return "char";
    case PlyScalar::UInt8:
      return "uchar";
    case PlyScalar::Int16:
      return "short";
    case PlyScalar::UInt16:
      return "ushort";
    case PlyScalar::Int32:
      return "int";
    case PlyScalar::UInt32:
      return "uint";
    case PlyScalar::Float32:
      return "float";
    case PlyScalar::Float64:
      return "double";
  }
  return "?";
}

PlyHeader parsePlyHeader(InputBuffer& input, const std::string& name) {
  return HeaderParser(input, name).parse();
}

}  // namespace facetree::stream_detail
