#include "test_util.h"

#include <zstd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

namespace facetree::test {

TempDir::TempDir() : TempDir(std::filesystem::path(::testing::TempDir())) {}

TempDir::TempDir(const std::filesystem::path& base) {
  const std::filesystem::path root =
      std::filesystem::is_directory(base) ? base : std::filesystem::path(::testing::TempDir());
  std::string pattern = (root / "facetree_stream_XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  path_ = pattern;
}

TempDir::~TempDir() {
  std::error_code ignored;
  std::filesystem::remove_all(path_, ignored);
}

std::filesystem::path TempDir::write(const std::string& name, const std::string& bytes) const {
  const std::filesystem::path file = path_ / name;
  std::ofstream out(file, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + file.string());
  return file;
}

SimpleMesh pyramid() {
  return SimpleMesh{{{0, 0, 0}, {1.5f, 0, 0}, {1.5f, 1.25f, 0}, {0, 1.25f, -0.0f}, {0.75f, 0.5f, 2.0f}},
                    {{0, 3, 2, 1}, {0, 1, 4}, {1, 2, 4}, {2, 3, 4}, {3, 0, 4}}};
}

SimpleMesh squareGrid(int side, float cell, const std::function<float(int, int)>& height) {
  SimpleMesh mesh;
  for (int j = 0; j <= side; ++j)
    for (int i = 0; i <= side; ++i)
      mesh.vertices.emplace_back(float(i) * cell, float(j) * cell, height(i, j));
  for (int j = 0; j < side; ++j)
    for (int i = 0; i < side; ++i) {
      const int64_t v = j * (side + 1) + i;
      mesh.faces.push_back({v, v + 1, v + side + 2});
      mesh.faces.push_back({v, v + side + 2, v + side + 1});
    }
  return mesh;
}

SimpleMesh dirtyGrid(int side, uint32_t seed) {
  SimpleMesh mesh = squareGrid(side, 0.5f, [](int i, int j) { return std::sin(0.3f * i) * float(j); });
  std::mt19937 random(seed);
  std::shuffle(mesh.faces.begin(), mesh.faces.end(), random);
  mesh.faces[3] = {mesh.faces[3][0], mesh.faces[3][0], mesh.faces[3][1]};
  mesh.vertices[5].y = std::numeric_limits<float>::quiet_NaN();
  mesh.vertices[7].z = -0.0f;
  return mesh;
}

std::vector<Triangle> expectedTriangles(const SimpleMesh& mesh) {
  std::vector<Triangle> triangles;
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& face = mesh.faces[f];
    for (size_t k = 2; k < face.size(); ++k) {
      Triangle t{};
      const int64_t corners[3] = {face[0], face[k - 1], face[k]};
      for (int c = 0; c < 3; ++c) {
        t.vertex[c] = static_cast<uint32_t>(corners[c]);
        t.position[c] = mesh.vertices[static_cast<size_t>(corners[c])];
      }
      t.face = f;
      triangles.push_back(t);
    }
  }
  return triangles;
}

void appendBinary(std::string& out, const std::string& type, double value, bool bigEndian) {
  char bytes[8];
  size_t size = 0;
  auto put = [&](auto typed) {
    size = sizeof(typed);
    std::memcpy(bytes, &typed, size);
  };
  if (type == "char" || type == "int8")
    put(static_cast<int8_t>(value));
  else if (type == "uchar" || type == "uint8")
    put(static_cast<uint8_t>(value));
  else if (type == "short" || type == "int16")
    put(static_cast<int16_t>(value));
  else if (type == "ushort" || type == "uint16")
    put(static_cast<uint16_t>(value));
  else if (type == "int" || type == "int32")
    put(static_cast<int32_t>(value));
  else if (type == "uint" || type == "uint32")
    put(static_cast<uint32_t>(value));
  else if (type == "float" || type == "float32")
    put(static_cast<float>(value));
  else if (type == "double" || type == "float64")
    put(value);
  else
    throw std::runtime_error("bad type " + type);
  if (bigEndian != (std::endian::native == std::endian::big)) std::reverse(bytes, bytes + size);
  out.append(bytes, size);
}

namespace {
std::string number(double value) {
  std::ostringstream text;
  text.precision(17);
  text << value;
  return text.str();
}

// "x y z" (avoids "literal" + std::string, which trips a gcc 12 -Wrestrict false positive).
std::string coordinates(const glm::vec3& p) {
  std::string text = number(p.x);
  text.append(" ").append(number(p.y)).append(" ").append(number(p.z));
  return text;
}
}  // namespace

std::string writePly(const SimpleMesh& mesh, const PlyOptions& o) {
  const std::string eol = o.crlfHeader ? "\r\n" : "\n";
  const bool ascii = o.encoding == "ascii";
  const bool big = o.encoding == "binary_big_endian";
  std::string header = "ply" + eol + "format " + o.encoding + " 1.0" + eol;
  if (o.comments) header += "comment made by facetree tests" + eol + "obj_info nothing" + eol;
  std::string vertexHeader = "element vertex " + std::to_string(mesh.vertices.size()) + eol;
  if (o.extraProperties) vertexHeader += "property uchar red" + eol + "property list uchar short junk" + eol;
  for (const char* axis : {"x", "y", "z"}) vertexHeader += "property " + o.coordinateType + " " + axis + eol;
  if (o.extraProperties) vertexHeader += "property double confidence" + eol;
  std::string faceHeader = "element face " + std::to_string(mesh.faces.size()) + eol;
  if (o.extraProperties) faceHeader += "property int flags" + eol;
  faceHeader += "property list " + o.countType + " " + o.indexType + " " + o.indexName + eol;
  if (o.extraProperties)
    faceHeader += "property list uchar float texcoord" + eol + "property ushort material" + eol;
  const std::string extraHeader =
      "element material 2" + eol + "property list int uchar name" + eol + "property float shininess" + eol;

  std::string vertexData, faceData, extraData;
  auto value = [&](std::string& out, const std::string& type, double v, bool last = false) {
    if (ascii) {
      out += number(v);
      out += last ? "\n" : " ";
    } else {
      appendBinary(out, type, v, big);
    }
  };
  for (const glm::vec3& p : mesh.vertices) {
    if (o.extraProperties) {
      value(vertexData, "uchar", 200);
      value(vertexData, "uchar", 2);
      value(vertexData, "short", -7);
      value(vertexData, "short", 9);
    }
    value(vertexData, o.coordinateType, p.x);
    value(vertexData, o.coordinateType, p.y);
    value(vertexData, o.coordinateType, p.z, !o.extraProperties);
    if (o.extraProperties) value(vertexData, "double", 0.5, true);
  }
  for (const auto& face : mesh.faces) {
    if (o.extraProperties) value(faceData, "int", -3);
    value(faceData, o.countType, static_cast<double>(face.size()));
    for (size_t k = 0; k < face.size(); ++k)
      value(faceData, o.indexType, static_cast<double>(face[k]), !o.extraProperties && k + 1 == face.size());
    if (o.extraProperties) {
      value(faceData, "uchar", 2);
      value(faceData, "float", 0.25);
      value(faceData, "float", 0.75);
      value(faceData, "ushort", 3, true);
    }
  }
  for (int m = 0; m < 2; ++m) {
    value(extraData, "int", 3);
    for (int k = 0; k < 3; ++k) value(extraData, "uchar", 'a' + k);
    value(extraData, "float", 1.5, true);
  }
  std::string ply = header;
  if (o.facesFirst)
    ply += faceHeader + (o.extraElement ? extraHeader : "") + vertexHeader;
  else
    ply += vertexHeader + (o.extraElement ? extraHeader : "") + faceHeader;
  ply += "end_header" + eol;
  if (o.facesFirst)
    ply += faceData + (o.extraElement ? extraData : "") + vertexData;
  else
    ply += vertexData + (o.extraElement ? extraData : "") + faceData;
  return ply;
}

std::string writeObj(const SimpleMesh& mesh) {
  std::string obj = "# pyramid\nmtllib none.mtl\no pyramid\n";
  for (const glm::vec3& p : mesh.vertices) obj.append("v ").append(coordinates(p)).append("\n");
  obj += "vt 0 0\nvn 0 0 1\ns off\nusemtl stone\n";
  for (const auto& face : mesh.faces) {
    obj += "f";
    for (const int64_t index : face) obj.append(" ").append(std::to_string(index + 1));
    obj += "\n";
  }
  return obj;
}

std::string writeAsciiStl(const SimpleMesh& mesh) {
  std::string stl = "solid pyramid\n";
  for (const Triangle& t : expectedTriangles(mesh)) {
    stl += "  facet normal 0 0 0\n    outer loop\n";
    for (const glm::vec3& p : t.position) stl.append("      vertex ").append(coordinates(p)).append("\n");
    stl += "    endloop\n  endfacet\n";
  }
  return stl + "endsolid pyramid\n";
}

std::string writeBinaryStl(const SimpleMesh& mesh, const std::string& header) {
  std::string stl = header;
  stl.resize(80, ' ');
  const std::vector<Triangle> triangles = expectedTriangles(mesh);
  appendBinary(stl, "uint", static_cast<double>(triangles.size()), false);
  for (const Triangle& t : triangles) {
    for (int k = 0; k < 3; ++k) appendBinary(stl, "float", 0, false);
    for (const glm::vec3& p : t.position)
      for (int k = 0; k < 3; ++k) appendBinary(stl, "float", p[k], false);
    appendBinary(stl, "ushort", 0, false);
  }
  return stl;
}

std::string zstdCompress(const std::string& bytes, int level) {
  std::string out(ZSTD_compressBound(bytes.size()), '\0');
  const size_t size = ZSTD_compress(out.data(), out.size(), bytes.data(), bytes.size(), level);
  if (ZSTD_isError(size)) throw std::runtime_error("ZSTD_compress failed");
  out.resize(size);
  return out;
}

ReadBack readBytes(const std::string& name, const std::string& bytes, size_t batch) {
  const TempDir dir;
  ReadBack back;
  back.reader = openMesh(dir.write(name, bytes));
  back.triangles = readAll(*back.reader, batch);
  return back;
}

std::vector<std::array<uint32_t, 3>> cornersOf(const std::vector<Triangle>& triangles) {
  std::vector<std::array<uint32_t, 3>> corners;
  corners.reserve(triangles.size());
  for (const Triangle& t : triangles) corners.push_back({t.vertex[0], t.vertex[1], t.vertex[2]});
  return corners;
}

std::vector<Triangle> readAll(TriangleReader& reader, size_t batch) {
  std::vector<Triangle> all;
  std::vector<Triangle> buffer(batch);
  while (const size_t count = reader.read(buffer))
    all.insert(all.end(), buffer.begin(), buffer.begin() + count);
  return all;
}

std::vector<Triangle> readFile(const std::filesystem::path& path, size_t batch) {
  auto reader = openMesh(path);
  return readAll(*reader, batch);
}

std::string errorOf(const std::function<void()>& action) {
  try {
    action();
  } catch (const Error& error) {
    return error.what();
  }
  ADD_FAILURE() << "no ReadError thrown";
  return "";
}

bool sameTriangles(const std::vector<Triangle>& a, const std::vector<Triangle>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].face != b[i].face) return false;
    for (int c = 0; c < 3; ++c)
      if (a[i].vertex[c] != b[i].vertex[c] || a[i].position[c] != b[i].position[c]) return false;
  }
  return true;
}

std::string describe(const std::vector<Triangle>& triangles) {
  std::ostringstream text;
  for (const Triangle& t : triangles) {
    text << "f" << t.face << " [";
    for (int c = 0; c < 3; ++c)
      text << t.vertex[c] << ":(" << t.position[c].x << "," << t.position[c].y << "," << t.position[c].z
           << ") ";
    text << "]\n";
  }
  return text.str();
}

}  // namespace facetree::test
