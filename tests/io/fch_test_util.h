// Test helpers for the cluster file: in-memory meshes, a test-only binary hierarchy builder
// (recursive median split of face centroids, in the merge.h layout) with brute-force boxes.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include "../merge/test_meshes.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/stream.h"

namespace facetree::test {

// A mesh file read whole into memory.
inline IndexedMesh load(const std::filesystem::path& path) {
  auto reader = openMesh(path);
  return loadMesh(*reader);
}

// A w x h grid of squares, two triangles each, on a gently curved sheet.
inline TestMesh gridMesh(int w, int h, float bend = 0.1f) {
  TestMesh m;
  for (int y = 0; y <= h; ++y)
    for (int x = 0; x <= w; ++x)
      m.positions.push_back({float(x), float(y), bend * std::sin(0.3f * x) * std::cos(0.2f * y)});
  auto v = [&](int x, int y) { return static_cast<uint32_t>(y * (w + 1) + x); };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      m.indices.insert(m.indices.end(), {v(x, y), v(x + 1, y), v(x + 1, y + 1)});
      m.indices.insert(m.indices.end(), {v(x, y), v(x + 1, y + 1), v(x, y + 1)});
    }
  return m;
}

// Binary hierarchy by recursive median split of centroids (longest axis), iterative; nodes[0]
// is the root and children follow their parents, as buildHierarchy lays them out. Statistics
// and axis-aligned boxes are brute force from the triangles.
inline Hierarchy medianSplitHierarchy(const MeshView& mesh) {
  const size_t n = mesh.triangleCount();
  Hierarchy h;
  h.faceOrder.resize(n);
  for (size_t i = 0; i < n; ++i) h.faceOrder[i] = static_cast<uint32_t>(i);
  auto corner = [&](uint32_t t, int k) { return mesh.positions[mesh.indices[3 * size_t{t} + k]]; };
  auto centroid = [&](uint32_t t) { return (corner(t, 0) + corner(t, 1) + corner(t, 2)) / 3.0f; };
  if (n < 2) return h;
  struct Item {
    uint32_t node, first, count;
  };
  std::vector<Item> stack{{0, 0, static_cast<uint32_t>(n)}};
  h.nodes.push_back({});
  while (!stack.empty()) {
    const Item item = stack.back();
    stack.pop_back();
    auto begin = h.faceOrder.begin() + item.first, end = begin + item.count;
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (auto it = begin; it != end; ++it) lo = glm::min(lo, centroid(*it)), hi = glm::max(hi, centroid(*it));
    const glm::vec3 size = hi - lo;
    const int axis = size.x >= size.y && size.x >= size.z ? 0 : (size.y >= size.z ? 1 : 2);
    const uint32_t half = item.count / 2;
    std::nth_element(begin, begin + half, end, [&](uint32_t a, uint32_t b) {
      const float ca = centroid(a)[axis], cb = centroid(b)[axis];
      return ca != cb ? ca < cb : a < b;
    });
    Node& node = h.nodes[item.node];
    node.first = item.first;
    node.count = item.count;
    const uint32_t parts[2][2] = {{item.first, half}, {item.first + half, item.count - half}};
    for (int c = 0; c < 2; ++c) {
      if (parts[c][1] == 1) {
        h.nodes[item.node].child[c] = kFaceChild | parts[c][0];
      } else {
        const auto index = static_cast<uint32_t>(h.nodes.size());
        h.nodes[item.node].child[c] = index;
        h.nodes.push_back({});
        stack.push_back({index, parts[c][0], parts[c][1]});
      }
    }
  }
  // Statistics and boxes over the final face order.
  h.boxes.resize(h.nodes.size());
  for (size_t j = 0; j < h.nodes.size(); ++j) {
    Node& node = h.nodes[j];
    glm::dvec3 lo(INFINITY), hi(-INFINITY), s(0.0);
    double area = 0, side[6] = {0, 0, 0, 0, 0, 0};
    for (uint32_t p = node.first; p < node.first + node.count; ++p) {
      const uint32_t t = h.faceOrder[p];
      const glm::dvec3 a(corner(t, 0)), b(corner(t, 1)), c(corner(t, 2));
      for (const glm::dvec3& q : {a, b, c}) lo = glm::min(lo, q), hi = glm::max(hi, q);
      const glm::dvec3 an = 0.5 * glm::cross(b - a, c - a);
      area += glm::length(an);
      s += an;
      for (int k = 0; k < 3; ++k)
        side[2 * k] += std::max(an[k], 0.0), side[2 * k + 1] += std::max(-an[k], 0.0);
    }
    node.area = float(area);
    node.sumNormal = glm::vec3(s);
    node.cost = float(j);
    node.perimeter = float(2 * j);
    node.flags = j % 3 == 0 ? uint32_t{kNodeFlatFrame} : 0u;
    NodeBox& box = h.boxes[j];
    box.center = glm::vec3(0.5 * (lo + hi));
    box.orientation = glm::quat(1, 0, 0, 0);
    box.halfExtent = glm::vec3(0.5 * (hi - lo));
    for (int k = 0; k < 6; ++k) box.sideArea[k] = float(side[k]);
  }
  return h;
}

inline std::filesystem::path scratch(const std::string& name) {
  return std::filesystem::temp_directory_path() / ("facetree_fch_" + std::to_string(::getpid()) + "_" + name);
}

inline std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
inline void spit(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// Field-by-field node equality (NodeBox has no operator==).
// `read` as a version 2 file with exact boxes gives back `written` (docs/FORMAT.md): structure,
// costs, areas, perimeters, centres and orientations exactly; S within 2^-12 of the area a
// component, side areas within 2^-11 of it; half extents at least the written ones and at most
// 2^-17 of the largest written one above them.
inline bool sameNode(const FchNode& read, const FchNode& written) {
  const FchNode &a = read, &b = written;
  if (a.first != b.first || a.count != b.count || a.childCount != b.childCount || a.flags != b.flags)
    return false;
  if (!std::equal(a.child, a.child + a.childCount, b.child)) return false;
  if (!std::equal(a.childFaces, a.childFaces + a.childCount, b.childFaces)) return false;
  if (a.cost != b.cost || a.area != b.area || a.perimeter != b.perimeter) return false;
  if (a.box.center != b.box.center || a.box.orientation != b.box.orientation) return false;
  const double area = b.area,
               largest = std::max({b.box.halfExtent.x, b.box.halfExtent.y, b.box.halfExtent.z});
  for (int k = 0; k < 3; ++k) {
    if (std::abs(double(a.sumNormal[k]) - b.sumNormal[k]) > 0x1p-12 * area * 1.001) return false;
    const double over = double(a.box.halfExtent[k]) - b.box.halfExtent[k];
    if (over < 0 || over > 0x1p-17 * largest) return false;
  }
  for (int k = 0; k < 6; ++k)
    if (std::abs(double(a.box.sideArea[k]) - b.box.sideArea[k]) > 0x1p-11 * area * 1.001) return false;
  return true;
}

// Removes the listed files when the test ends.
struct Cleanup {
  std::vector<std::filesystem::path> paths;
  ~Cleanup() {
    for (const auto& p : paths) {
      std::error_code ignored;
      std::filesystem::remove(p, ignored);
    }
  }
  const std::filesystem::path& add(const std::filesystem::path& p) { return paths.emplace_back(p); }
};

}  // namespace facetree::test
