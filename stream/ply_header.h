// Internal: PLY header model and parser.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "byte_source.h"

namespace facetree::stream_detail {

enum class PlyEncoding { Ascii, BinaryLittleEndian, BinaryBigEndian };
enum class PlyScalar : uint8_t { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

size_t scalarSize(PlyScalar type);
bool isInteger(PlyScalar type);
const char* scalarName(PlyScalar type);

struct PlyProperty {
  std::string name;
  PlyScalar type = PlyScalar::Float32;  // item type for lists
  bool isList = false;
  PlyScalar countType = PlyScalar::UInt8;
};

// What the reader does with an element.
enum class PlyRole { Vertex, Face, TriStrips, Other };

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;
  uint64_t line = 0;  // header line of the "element" statement
  PlyRole role = PlyRole::Other;
  int coordinate[3] = {-1, -1, -1};  // vertex: property index of x, y, z
  int indexList = -1;                // face/tristrips: property index of vertex_indices
};

struct PlyHeader {
  PlyEncoding encoding = PlyEncoding::Ascii;
  std::vector<PlyElement> elements;
  uint64_t lines = 0;  // header lines including "ply" and "end_header"
  int vertexElement = -1;
};

// Parses the header from the start of `input` (which begins with "ply") through end_header and
// checks that it describes a mesh: a vertex element with scalar x, y, z and a face or tristrips
// element with an integer vertex_indices (or vertex_index) list. Throws Error (Input) "line N: ...".
PlyHeader parsePlyHeader(InputBuffer& input, const std::string& name);

}  // namespace facetree::stream_detail
