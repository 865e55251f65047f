// Small mesh generators and hierarchy checks for the merge tests.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <numeric>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "facetree/merge.h"

namespace facetree::test {

struct TestMesh {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  MeshView view() const { return {positions, indices}; }
  uint32_t faceCount() const { return static_cast<uint32_t>(indices.size() / 3); }
  void add(uint32_t a, uint32_t b, uint32_t c) { indices.insert(indices.end(), {a, b, c}); }
  // Appends `other` with its indices shifted and its positions moved by `offset`.
  void append(const TestMesh& other, glm::vec3 offset = glm::vec3(0)) {
    const uint32_t base = static_cast<uint32_t>(positions.size());
    for (const glm::vec3& p : other.positions) positions.push_back(p + offset);
    for (uint32_t i : other.indices) indices.push_back(base + i);
  }
};

// Flat square grid of m x m cells, 2 m^2 triangles, in the z = 0 plane, cell size `cell`.
inline TestMesh grid(uint32_t m, float cell = 1.0f) {
  TestMesh mesh;
  for (uint32_t y = 0; y <= m; ++y) {
    for (uint32_t x = 0; x <= m; ++x) mesh.positions.emplace_back(x * cell, y * cell, 0.0f);
  }
  for (uint32_t y = 0; y < m; ++y) {
    for (uint32_t x = 0; x < m; ++x) {
      const uint32_t v = y * (m + 1) + x;
      mesh.add(v, v + 1, v + m + 2);
      mesh.add(v, v + m + 2, v + m + 1);
    }
  }
  return mesh;
}

// A strip of `count` triangles along x (a chain in the dual graph).
inline TestMesh strip(uint32_t count) {
  TestMesh mesh;
  const uint32_t columns = (count + 1) / 2 + 1;
  for (uint32_t x = 0; x < columns; ++x) {
    mesh.positions.emplace_back(float(x), 0.0f, 0.0f);
    mesh.positions.emplace_back(float(x), 1.0f, 0.0f);
  }
  for (uint32_t t = 0; t < count; ++t) {
    const uint32_t x = t / 2, b = 2 * x;
    if (t % 2 == 0) {
      mesh.add(b, b + 2, b + 1);
    } else {
      mesh.add(b + 1, b + 2, b + 3);
    }
  }
  return mesh;
}

inline TestMesh tetrahedron() {
  TestMesh mesh;
  mesh.positions = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
  mesh.add(0, 1, 2);
  mesh.add(0, 3, 1);
  mesh.add(0, 2, 3);
  mesh.add(1, 3, 2);
  return mesh;
}

inline TestMesh cube() {
  TestMesh mesh;
  for (int i = 0; i < 8; ++i) mesh.positions.emplace_back(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1);
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    mesh.add(q[0], q[1], q[2]);
    mesh.add(q[0], q[2], q[3]);
  }
  return mesh;
}

// Icosphere of radius 1: 20 * 4^levels triangles, closed manifold.
inline TestMesh icosphere(int levels) {
  TestMesh mesh;
  const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
  mesh.positions = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                    {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  mesh.indices = {0, 11, 5,  0, 5,  1, 0, 1, 7, 0, 7,  10, 0, 10, 11, 1, 5, 9, 5, 11,
                  4, 11, 10, 2, 10, 7, 6, 7, 1, 8, 3,  9,  4, 3,  4,  2, 3, 2, 6, 3,
                  6, 8,  3,  8, 9,  4, 9, 5, 2, 4, 11, 6,  2, 10, 8,  6, 7, 9, 8, 1};
  for (glm::vec3& p : mesh.positions) p = glm::normalize(p);
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> midpoints;
    auto midpoint = [&](uint32_t a, uint32_t b) {
      const auto key = std::minmax(a, b);
      auto [it, inserted] = midpoints.try_emplace({key.first, key.second}, 0);
      if (inserted) {
        it->second = static_cast<uint32_t>(mesh.positions.size());
        mesh.positions.push_back(glm::normalize(mesh.positions[a] + mesh.positions[b]));
      }
      return it->second;
    };
    std::vector<uint32_t> refined;
    for (size_t f = 0; f + 2 < mesh.indices.size(); f += 3) {
      const uint32_t a = mesh.indices[f], b = mesh.indices[f + 1], c = mesh.indices[f + 2];
      const uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      refined.insert(refined.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    mesh.indices = std::move(refined);
  }
  return mesh;
}

// A flat disc of `rings` rings of `sectors` quads (two triangles each) around a fan, whose
// radii grow by `growth` per ring: triangle sizes grade geometrically outward, like the
// meshes around a building's footprint in an architectural model. Eq. 84 alone grows the central cluster by
// absorbing one ever larger neighbour at a time (perim^2/projArea favours the compact one).
inline TestMesh gradedDisc(uint32_t rings, uint32_t sectors, float growth) {
  TestMesh mesh;
  mesh.positions.emplace_back(0.0f, 0.0f, 0.0f);
  constexpr float kTwoPi = 6.2831853f;
  float radius = 1.0f;
  for (uint32_t r = 0; r < rings; ++r, radius *= growth) {
    // Alternate rings are rotated by half a sector so the triangles stay well shaped.
    const float offset = (r % 2) * 0.5f;
    for (uint32_t s = 0; s < sectors; ++s) {
      const float angle = kTwoPi * (float(s) + offset) / float(sectors);
      mesh.positions.emplace_back(radius * std::cos(angle), radius * std::sin(angle), 0.0f);
    }
  }
  const auto vertex = [&](uint32_t r, uint32_t s) { return 1 + r * sectors + s % sectors; };
  for (uint32_t s = 0; s < sectors; ++s) mesh.add(0, vertex(0, s), vertex(0, s + 1));
  for (uint32_t r = 0; r + 1 < rings; ++r) {
    for (uint32_t s = 0; s < sectors; ++s) {
      mesh.add(vertex(r, s), vertex(r + 1, s), vertex(r, s + 1));
      mesh.add(vertex(r, s + 1), vertex(r + 1, s), vertex(r + 1, s + 1));
    }
  }
  return mesh;
}

// --- checks -------------------------------------------------------------------------------

struct Layout {
  std::vector<uint32_t> parent;      // per node, ~0 for the root
  std::vector<uint32_t> depth;       // root 1
  std::vector<uint32_t> faceParent;  // per face position: the node holding it as a child
};

// Nodes by decreasing effective cost (the maximum of a node's cost and its children's).
inline void checkEffectiveCostOrder(const Hierarchy& h) {
  std::vector<float> effective(h.nodes.size());
  for (size_t i = h.nodes.size(); i-- > 0;) {
    float e = h.nodes[i].cost;
    for (const uint32_t child : h.nodes[i].child)
      if (!(child & kFaceChild) && child > i && child < h.nodes.size()) e = std::max(e, effective[child]);
    effective[i] = e;
  }
  for (size_t i = 1; i < effective.size(); ++i) {
    if (!(effective[i] <= effective[i - 1])) {
      ADD_FAILURE() << "node " << i << " has effective cost " << effective[i] << " above node " << i - 1
                    << "'s " << effective[i - 1];
      return;
    }
  }
}

inline uint32_t childCount(const Hierarchy& h, uint32_t child) {
  return (child & kFaceChild) ? 1 : h.nodes[child].count;
}

// Structural invariants: node count, permutation, contiguous nested ranges, children after
// parents, finite costs. Returns parent/depth tables for further checks.
inline Layout checkStructure(const Hierarchy& h, uint32_t n) {
  Layout layout;
  EXPECT_EQ(h.nodes.size(), size_t{n} - 1);
  EXPECT_EQ(h.faceOrder.size(), size_t{n});
  std::vector<uint32_t> sorted = h.faceOrder;
  std::sort(sorted.begin(), sorted.end());
  for (uint32_t i = 0; i < sorted.size(); ++i) {
    if (sorted[i] != i) {
      ADD_FAILURE() << "faceOrder is not a permutation";
      break;
    }
  }
  layout.parent.assign(h.nodes.size(), ~0u);
  layout.depth.assign(h.nodes.size(), 0);
  layout.faceParent.assign(n, ~0u);
  if (h.nodes.empty()) return layout;
  EXPECT_EQ(h.nodes[0].first, 0u);
  EXPECT_EQ(h.nodes[0].count, n);
  layout.depth[0] = 1;
  for (uint32_t i = 0; i < h.nodes.size(); ++i) {
    const Node& node = h.nodes[i];
    EXPECT_TRUE(std::isfinite(node.cost)) << "node " << i;
    EXPECT_TRUE(std::isfinite(node.area) && std::isfinite(node.perimeter)) << "node " << i;
    uint32_t first = node.first;
    for (uint32_t child : node.child) {
      if (child & kFaceChild) {
        const uint32_t pos = child & ~kFaceChild;
        EXPECT_EQ(pos, first) << "node " << i;
        if (pos < n) layout.faceParent[pos] = i;
        first += 1;
      } else {
        EXPECT_GT(child, i);
        EXPECT_LT(child, h.nodes.size());
        if (child <= i || child >= h.nodes.size()) return layout;
        EXPECT_EQ(h.nodes[child].first, first) << "node " << i;
        EXPECT_EQ(layout.parent[child], ~0u) << "node " << child << " has two parents";
        layout.parent[child] = i;
        layout.depth[child] = layout.depth[i] + 1;
        first += h.nodes[child].count;
      }
    }
    EXPECT_EQ(first, node.first + node.count) << "children do not partition node " << i;
  }
  for (uint32_t i = 1; i < h.nodes.size(); ++i) EXPECT_NE(layout.parent[i], ~0u) << "orphan node " << i;
  for (uint32_t p = 0; p < n; ++p) EXPECT_NE(layout.faceParent[p], ~0u) << "face position " << p;
  uint32_t height = 1;
  for (uint32_t p = 0; p < n; ++p) height = std::max(height, layout.depth[layout.faceParent[p]] + 1);
  EXPECT_EQ(h.stats.height, height);
  return layout;
}

// Every node is edge-connected (some mesh edge joins its two children), unless it is flagged
// as joining disjoint surfaces, in which case no mesh edge joins them. Marks the lowest common
// ancestor of every adjacent face pair.
inline void checkConnectivity(const Hierarchy& h, const TestMesh& mesh, const Layout& layout) {
  const uint32_t n = mesh.faceCount();
  if (n < 2) return;
  std::vector<uint32_t> position(n);
  for (uint32_t p = 0; p < n; ++p) position[h.faceOrder[p]] = p;
  std::map<std::pair<uint32_t, uint32_t>, std::vector<uint32_t>> edgeFaces;
  for (uint32_t f = 0; f < n; ++f) {
    for (int i = 0; i < 3; ++i) {
      const uint32_t a = mesh.indices[3 * f + i], b = mesh.indices[3 * f + (i + 1) % 3];
      if (a == b) continue;
      auto& faces = edgeFaces[std::minmax(a, b)];
      if (faces.empty() || faces.back() != f) faces.push_back(f);
    }
  }
  std::vector<char> crossed(h.nodes.size(), 0);
  for (const auto& [edge, faces] : edgeFaces) {
    for (size_t i = 0; i < faces.size(); ++i) {
      for (size_t j = i + 1; j < faces.size(); ++j) {
        uint32_t u = layout.faceParent[position[faces[i]]], v = layout.faceParent[position[faces[j]]];
        while (u != v) {
          if (layout.depth[u] >= layout.depth[v]) {
            u = layout.parent[u];
          } else {
            v = layout.parent[v];
          }
        }
        crossed[u] = 1;
      }
    }
  }
  for (uint32_t i = 0; i < h.nodes.size(); ++i) {
    const bool flagged = h.nodes[i].flags & kNodeJoinsDisjointSurfaces;
    EXPECT_NE(bool(crossed[i]), flagged)
        << "node " << i << (flagged ? " flagged but connected" : " not connected");
  }
}

// Area, S and perimeter of every node against brute force over its faces (manifold meshes:
// the perimeter is the length of the mesh edges used by exactly one of the node's faces).
inline void checkStats(const Hierarchy& h, const TestMesh& mesh, double tolerance) {
  const uint32_t n = mesh.faceCount();
  double totalArea = 0, totalLength = 0;
  for (uint32_t f = 0; f < n; ++f) {
    const glm::dvec3 a(mesh.positions[mesh.indices[3 * f]]), b(mesh.positions[mesh.indices[3 * f + 1]]),
        c(mesh.positions[mesh.indices[3 * f + 2]]);
    totalArea += 0.5 * glm::length(glm::cross(b - a, c - a));
    totalLength += glm::length(b - a) + glm::length(c - b) + glm::length(a - c);
  }
  for (uint32_t i = 0; i < h.nodes.size(); ++i) {
    const Node& node = h.nodes[i];
    double area = 0, perimeter = 0;
    glm::dvec3 s(0.0);
    std::map<std::pair<uint32_t, uint32_t>, int> uses;
    for (uint32_t p = node.first; p < node.first + node.count; ++p) {
      const uint32_t f = h.faceOrder[p];
      const uint32_t* v = &mesh.indices[3 * f];
      const glm::dvec3 a(mesh.positions[v[0]]), b(mesh.positions[v[1]]), c(mesh.positions[v[2]]);
      const glm::dvec3 cross = glm::cross(b - a, c - a);
      area += 0.5 * glm::length(cross);
      s += 0.5 * cross;
      for (int k = 0; k < 3; ++k) ++uses[std::minmax(v[k], v[(k + 1) % 3])];
    }
    for (const auto& [edge, count] : uses) {
      if (count == 1)
        perimeter += glm::length(glm::dvec3(mesh.positions[edge.first] - mesh.positions[edge.second]));
    }
    EXPECT_NEAR(node.area, area, tolerance * totalArea) << "node " << i;
    EXPECT_NEAR(node.perimeter, perimeter, tolerance * totalLength) << "node " << i;
    EXPECT_NEAR(node.sumNormal.x, s.x, tolerance * totalArea) << "node " << i;
    EXPECT_NEAR(node.sumNormal.y, s.y, tolerance * totalArea) << "node " << i;
    EXPECT_NEAR(node.sumNormal.z, s.z, tolerance * totalArea) << "node " << i;
  }
}

inline uint64_t hashHierarchy(const Hierarchy& h) {
  uint64_t x = 1469598103934665603ull;
  auto mix = [&](uint32_t v) { x = (x ^ v) * 1099511628211ull; };
  for (const Node& node : h.nodes) {
    mix(node.child[0]);
    mix(node.child[1]);
    mix(node.first);
    mix(node.count);
    mix(node.flags);
    uint32_t bits;
    std::memcpy(&bits, &node.cost, 4);
    mix(bits);
  }
  for (uint32_t f : h.faceOrder) mix(f);
  return x;
}

// The merge order the tests build with: the default, or the exact greedy where the test target
// defines FACETREE_TEST_ORDER=Exact (merge_test.cpp runs under both).
#ifndef FACETREE_TEST_ORDER
#define FACETREE_TEST_ORDER Rounds
#endif
inline constexpr MergeOrder kTestOrder = MergeOrder::FACETREE_TEST_ORDER;

inline BuildOptions noBoxes(Metric metric = Metric::Willmott) {
  BuildOptions options;
  options.metric = metric;
  options.order = kTestOrder;
  options.computeBoxes = false;
  return options;
}

}  // namespace facetree::test
