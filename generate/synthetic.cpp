// Synthetic mesh generators (flat grid, sphere, terrain, strip, assembly, tiled scan, subdivision)
// streamed to PLY.
// Every shape computes any vertex and any triangle from its index, so a keyed bijection
// (io/permutation.h) can shuffle vertex and face order without memory proportional to size.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

#include <glm/geometric.hpp>

#include "facetree/generate.h"
#include "permutation.h"

namespace facetree {
namespace {

constexpr double kGridSize = 1000.0;     // side of the generated grids, in model units
constexpr double kTerrainRelief = 60.0;  // peak-to-valley height scale of the terrain
constexpr int kTerrainOctaves = 6;
constexpr uint32_t kMaxIndex = 0x7FFFFFFFu;  // PLY int indices

struct Tri {
  uint64_t v[3];
};

// A mesh whose vertices and triangles are computed from their index.
class IndexedShape {
 public:
  virtual ~IndexedShape() = default;
  virtual uint64_t vertexCount() const = 0;
  virtual uint64_t triangleCount() const = 0;
  virtual glm::dvec3 vertex(uint64_t i) const = 0;
  virtual Tri triangle(uint64_t j) const = 0;
};

uint64_t hash64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// Cells per side of a square grid of about `triangles` triangles.
uint64_t gridSide(uint64_t triangles) {
  return std::max<uint64_t>(1, static_cast<uint64_t>(std::llround(std::sqrt(triangles / 2.0))));
}

// Multi-octave value noise at (u, v) of the unit square: smooth, deterministic, any resolution.
double terrainHeight(uint64_t seed, double u, double v) {
  const auto lattice = [seed](int64_t x, int64_t y, int octave) {
    const uint64_t h =
        hash64(seed ^ hash64(static_cast<uint64_t>(x) * 0x100000001B3ull + static_cast<uint64_t>(y) +
                             (static_cast<uint64_t>(octave) << 56)));
    return static_cast<double>(h >> 11) * 0x1.0p-53;
  };
  double sum = 0, amplitude = 1, frequency = 4;
  for (int o = 0; o < kTerrainOctaves; ++o, amplitude *= 0.5, frequency *= 2) {
    const double x = u * frequency, y = v * frequency;
    const double fx = std::floor(x), fy = std::floor(y);
    const double tx = x - fx, ty = y - fy;
    const double sx = tx * tx * (3 - 2 * tx), sy = ty * ty * (3 - 2 * ty);
    const auto ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy);
    const double a = lattice(ix, iy, o), b = lattice(ix + 1, iy, o);
    const double c = lattice(ix, iy + 1, o), d = lattice(ix + 1, iy + 1, o);
    sum += amplitude * ((a + (b - a) * sx) * (1 - sy) + (c + (d - c) * sx) * sy);
  }
  return sum * kTerrainRelief;
}

class GridShape : public IndexedShape {
 public:
  // `columns` x `rows` square cells of two triangles; the model is kGridSize wide.
  GridShape(uint64_t columns, uint64_t rows, uint64_t seed, bool terrain)
      : columns_(columns), rows_(rows), seed_(seed), terrain_(terrain) {}
  uint64_t vertexCount() const override { return (columns_ + 1) * (rows_ + 1); }
  uint64_t triangleCount() const override { return 2 * columns_ * rows_; }
  glm::dvec3 vertex(uint64_t i) const override {
    const uint64_t x = i % (columns_ + 1), y = i / (columns_ + 1);
    const double u = static_cast<double>(x) / columns_, v = static_cast<double>(y) / columns_;
    return {u * kGridSize, v * kGridSize, terrain_ ? terrainHeight(seed_, u, v) : 0.0};
  }
  Tri triangle(uint64_t j) const override {
    const uint64_t quad = j / 2, x = quad % columns_, y = quad / columns_;
    const uint64_t a = y * (columns_ + 1) + x, b = a + 1, c = a + columns_ + 1, d = c + 1;
    return (j % 2 == 0) ? Tri{{a, b, d}} : Tri{{a, d, c}};
  }

 private:
  uint64_t columns_;
  uint64_t rows_;
  uint64_t seed_;
  bool terrain_;
};

// UV sphere: poles plus (rings-1) rings of 2*rings vertices.
class SphereShape : public IndexedShape {
 public:
  explicit SphereShape(uint64_t triangles) {
    rings_ = std::max<uint64_t>(2, static_cast<uint64_t>(std::llround(std::sqrt(triangles / 4.0))));
    segments_ = 2 * rings_;
  }
  uint64_t vertexCount() const override { return 2 + (rings_ - 1) * segments_; }
  uint64_t triangleCount() const override { return 2 * segments_ * (rings_ - 1); }
  glm::dvec3 vertex(uint64_t i) const override {
    if (i == 0) return {0, 0, 1};
    if (i == vertexCount() - 1) return {0, 0, -1};
    const uint64_t ring = (i - 1) / segments_ + 1, segment = (i - 1) % segments_;
    const double theta = std::numbers::pi * ring / rings_, phi = 2 * std::numbers::pi * segment / segments_;
    return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
  }
  Tri triangle(uint64_t j) const override {
    const uint64_t south = vertexCount() - 1;
    auto ringVertex = [&](uint64_t ring, uint64_t segment) {
      return 1 + (ring - 1) * segments_ + segment % segments_;
    };
    if (j < segments_) return Tri{{0, ringVertex(1, j), ringVertex(1, j + 1)}};
    j -= segments_;
    const uint64_t bands = rings_ - 2;
    if (j < 2 * segments_ * bands) {
      const uint64_t quad = j / 2, ring = quad / segments_ + 1, segment = quad % segments_;
      const uint64_t a = ringVertex(ring, segment), b = ringVertex(ring, segment + 1);
      const uint64_t c = ringVertex(ring + 1, segment), d = ringVertex(ring + 1, segment + 1);
      return (j % 2 == 0) ? Tri{{a, c, d}} : Tri{{a, d, b}};
    }
    j -= 2 * segments_ * bands;
    return Tri{{south, ringVertex(rings_ - 1, j + 1), ringVertex(rings_ - 1, j)}};
  }

 private:
  uint64_t rings_, segments_;
};

// A terrain scan delivered as tiles: the terrain's grid cut into kTiles x kTiles tiles that share no
// vertex (each stores its own border), and each tile in pieces of its own, as scans exported per
// tile and per material are: a material seam across it (two groups, unwelded), a hole of no data in
// the second group (its surround as four strips, unwelded), and one to six islands in the hole. Every piece
// is a rectangle of the grid with its own vertices, so any vertex and triangle follows from its index: a
// piece is found by binary search over the pieces' first vertices and triangles.
class TiledScanShape : public IndexedShape {
 public:
  TiledScanShape(uint64_t triangles, uint64_t seed) : seed_(seed) {
    const uint64_t tile = std::max<uint64_t>(kMinTileCells, gridSide(triangles) / kTiles);
    side_ = tile * kTiles;
    for (uint64_t t = 0; t < kTiles * kTiles; ++t) addTile((t % kTiles) * tile, (t / kTiles) * tile, tile, t);
  }
  uint64_t vertexCount() const override { return firstVertex_.back(); }
  uint64_t triangleCount() const override { return firstTriangle_.back(); }
  glm::dvec3 vertex(uint64_t i) const override {
    const size_t p = pieceOf(firstVertex_, i);
    const Piece& r = pieces_[p];
    const uint64_t local = i - firstVertex_[p], x = r.x0 + local % (r.w + 1), y = r.y0 + local / (r.w + 1);
    const double u = double(x) / double(side_), v = double(y) / double(side_);
    return {u * kGridSize, v * kGridSize, terrainHeight(seed_, u, v)};
  }
  Tri triangle(uint64_t j) const override {
    const size_t p = pieceOf(firstTriangle_, j);
    const Piece& r = pieces_[p];
    const uint64_t local = j - firstTriangle_[p], quad = local / 2, x = quad % r.w, y = quad / r.w;
    const uint64_t a = firstVertex_[p] + y * (r.w + 1) + x, b = a + 1, c = a + r.w + 1, d = c + 1;
    return (local % 2 == 0) ? Tri{{a, b, d}} : Tri{{a, d, c}};
  }

 private:
  static constexpr uint64_t kTiles = 9;
  static constexpr uint64_t kMinTileCells = 16;  // room for a seam, a hole and islands
  struct Piece {
    uint64_t x0, y0, w;  // from grid cell (x0, y0), w cells wide
  };

  // The piece of grid cells [x0, x1) x [y0, y1).
  void add(uint64_t x0, uint64_t y0, uint64_t x1, uint64_t y1) {
    pieces_.push_back({x0, y0, x1 - x0});
    firstVertex_.push_back(firstVertex_.back() + (x1 - x0 + 1) * (y1 - y0 + 1));
    firstTriangle_.push_back(firstTriangle_.back() + 2 * (x1 - x0) * (y1 - y0));
  }
  // A tile of s x s cells at (x, y): the seam at 30-60% of its width, the hole a third of the
  // second group's height and half its width, with one to six islands in it (an array of the
  // hole's parts, each a cell off its neighbours and the shore).
  void addTile(uint64_t x, uint64_t y, uint64_t s, uint64_t t) {
    const uint64_t h = hash64(seed_ ^ (t + 1) * 0x9E3779B97F4A7C15ull);
    const uint64_t seam = x + s * (3 + h % 4) / 10;
    const uint64_t hx0 = seam + (x + s - seam) / 4, hx1 = x + s - (x + s - seam) / 4;
    const uint64_t hy0 = y + s / 4 + (h >> 8) % (s / 4), hy1 = hy0 + s / 3;
    add(x, y, seam, y + s);        // the first material group
    add(seam, y, x + s, hy0);      // the second around its hole: below,
    add(seam, hy1, x + s, y + s);  // above,
    add(seam, hy0, hx0, hy1);      // left,
    add(hx1, hy0, x + s, hy1);     // and right of it
    const uint64_t across = std::clamp<uint64_t>(1 + (h >> 16) % 3, 1, (hx1 - hx0) / 3);
    const uint64_t up = std::clamp<uint64_t>(1 + (h >> 24) % 2, 1, (hy1 - hy0) / 3);
    for (uint64_t j = 0; j < up; ++j) {
      for (uint64_t i = 0; i < across; ++i) {
        const uint64_t ix0 = hx0 + (hx1 - hx0) * i / across, ix1 = hx0 + (hx1 - hx0) * (i + 1) / across;
        const uint64_t iy0 = hy0 + (hy1 - hy0) * j / up, iy1 = hy0 + (hy1 - hy0) * (j + 1) / up;
        add(ix0 + 1, iy0 + 1, ix1 - 1, iy1 - 1);  // an island
      }
    }
  }
  static size_t pieceOf(const std::vector<uint64_t>& first, uint64_t i) {
    return size_t(std::upper_bound(first.begin(), first.end(), i) - first.begin()) - 1;
  }

  uint64_t seed_, side_ = 0;
  std::vector<Piece> pieces_;
  std::vector<uint64_t> firstVertex_{0}, firstTriangle_{0};  // per piece, and the totals last
};

// A CAD-like assembly: two groups of closed boxes far apart (kAssemblyGroupGap box sizes). In each,
// six unit boxes stand touching in a 3 x 2 block, two more on top of it, and a ninth floats a
// quarter of a box off the block's side. Where two boxes touch, both store the face they share (as
// assemblies exported part by part do): the touching faces are there twice, with their own vertices.
// A box is the surface of an n x n x n lattice, its vertices shared between its sides; all of space
// is bent a little, the same for every part.
class AssemblyShape : public IndexedShape {
 public:
  explicit AssemblyShape(uint64_t triangles) {
    n_ = std::max<uint64_t>(1, static_cast<uint64_t>(std::llround(std::sqrt(triangles / (12.0 * kParts)))));
    perBox_ = (n_ + 1) * (n_ + 1) * 2 + (n_ - 1) * 4 * n_;
  }
  uint64_t vertexCount() const override { return kParts * perBox_; }
  uint64_t triangleCount() const override { return kParts * 12 * n_ * n_; }
  glm::dvec3 vertex(uint64_t i) const override {
    const uint64_t part = i / perBox_;
    const glm::dvec3 p = origin(part) + latticePoint(i % perBox_) / static_cast<double>(n_);
    // One smooth bend of space for every part: the boxes' sides curve (so that their cuts have a
    // fit error to compare), and faces that touch stay coincident.
    return p + kBend * glm::dvec3(std::sin(2.0 * p.y + 0.3), std::sin(2.0 * p.z + 1.1),
                                  std::sin(2.0 * p.x + 2.3));
  }
  Tri triangle(uint64_t j) const override {
    const uint64_t part = j / (12 * n_ * n_), local = j % (12 * n_ * n_);
    const uint64_t side = local / (2 * n_ * n_), quad = (local / 2) % (n_ * n_);
    const int axis = static_cast<int>(side / 2), u = (axis + 1) % 3, v = (axis + 2) % 3;
    const bool high = side % 2 == 1;
    const auto id = [&](uint64_t du, uint64_t dv) {
      uint64_t p[3];
      p[axis] = high ? n_ : 0;
      p[u] = quad % n_ + du;
      p[v] = quad / n_ + dv;
      return part * perBox_ + latticeId(p[0], p[1], p[2]);
    };
    // Counter-clockwise seen from outside: u x v points along +axis.
    const uint64_t a = id(0, 0), b = id(1, 0), c = id(1, 1), d = id(0, 1);
    if (local % 2 == 0) return high ? Tri{{a, b, c}} : Tri{{a, c, b}};
    return high ? Tri{{a, c, d}} : Tri{{a, d, c}};
  }

 private:
  static constexpr uint64_t kParts = 18;
  static constexpr double kAssemblyGroupGap = 30.0;
  static constexpr double kBend = 0.05;

  static glm::dvec3 origin(uint64_t part) {
    const uint64_t group = part / 9, k = part % 9;
    const glm::dvec3 base(group * kAssemblyGroupGap, 0.0, 0.0);
    if (k < 6) return base + glm::dvec3(double(k % 3), double(k / 3), 0.0);  // the 3 x 2 block
    if (k < 8) return base + glm::dvec3(double(k - 6), 0.0, 1.0);            // two on top
    return base + glm::dvec3(3.25, 0.0, 0.0);                                // one floating off
  }
  // Surface lattice points of [0, n]^3: the bottom layer, n - 1 rings of 4n, the top layer.
  uint64_t latticeId(uint64_t x, uint64_t y, uint64_t z) const {
    const uint64_t layer = (n_ + 1) * (n_ + 1);
    if (z == 0) return x + (n_ + 1) * y;
    if (z == n_) return layer + (n_ - 1) * 4 * n_ + x + (n_ + 1) * y;
    uint64_t ring;
    if (y == 0 && x < n_) {
      ring = x;
    } else if (x == n_ && y < n_) {
      ring = n_ + y;
    } else if (y == n_ && x > 0) {
      ring = 2 * n_ + (n_ - x);
    } else {
      ring = 3 * n_ + (n_ - y);
    }
    return layer + (z - 1) * 4 * n_ + ring;
  }
  glm::dvec3 latticePoint(uint64_t id) const {
    const uint64_t layer = (n_ + 1) * (n_ + 1), rings = (n_ - 1) * 4 * n_;
    if (id < layer) return {double(id % (n_ + 1)), double(id / (n_ + 1)), 0.0};
    id -= layer;
    if (id >= rings) {
      id -= rings;
      return {double(id % (n_ + 1)), double(id / (n_ + 1)), double(n_)};
    }
    const double z = double(id / (4 * n_) + 1);
    const uint64_t r = id % (4 * n_);
    if (r < n_) return {double(r), 0.0, z};
    if (r < 2 * n_) return {double(n_), double(r - n_), z};
    if (r < 3 * n_) return {double(n_ - (r - 2 * n_)), double(n_), z};
    return {0.0, double(n_ - (r - 3 * n_)), z};
  }
  uint64_t n_, perBox_;
};

// Subdivides every triangle of the input into s*s triangles, s = 2^levels, on the barycentric
// lattice (i, j), i + j <= s. Lattice points on input edges are numbered per edge (canonical
// direction from the lower vertex index) so neighbouring triangles share them.
class SubdividedShape : public IndexedShape {
 public:
  SubdividedShape(const MeshView& mesh, unsigned levels) : mesh_(mesh), s_(uint64_t{1} << levels) {
    const size_t n = mesh.triangleCount();
    std::vector<uint64_t> keys(3 * n);
    for (size_t f = 0; f < n; ++f)
      for (int k = 0; k < 3; ++k)
        keys[3 * f + k] = edgeKey(mesh.indices[3 * f + k], mesh.indices[3 * f + (k + 1) % 3]);
    edges_ = keys;
    std::sort(edges_.begin(), edges_.end());
    edges_.erase(std::unique(edges_.begin(), edges_.end()), edges_.end());
    faceEdges_.resize(3 * n);
    for (size_t i = 0; i < keys.size(); ++i)
      faceEdges_[i] =
          static_cast<uint64_t>(std::lower_bound(edges_.begin(), edges_.end(), keys[i]) - edges_.begin());
    interiorPerFace_ = (s_ - 1) * (s_ - 2) / 2;
  }
  uint64_t vertexCount() const override {
    return mesh_.positions.size() + edges_.size() * (s_ - 1) + mesh_.triangleCount() * interiorPerFace_;
  }
  uint64_t triangleCount() const override { return mesh_.triangleCount() * s_ * s_; }
  glm::dvec3 vertex(uint64_t i) const override {
    const uint64_t v = mesh_.positions.size();
    if (i < v) return glm::dvec3(mesh_.positions[i]);
    i -= v;
    if (i < edges_.size() * (s_ - 1)) {
      const uint64_t key = edges_[i / (s_ - 1)], step = i % (s_ - 1) + 1;
      const glm::dvec3 a(mesh_.positions[key >> 32]), b(mesh_.positions[key & 0xFFFFFFFFu]);
      return a + (b - a) * (static_cast<double>(step) / s_);
    }
    i -= edges_.size() * (s_ - 1);
    const uint64_t f = i / interiorPerFace_;
    uint64_t k = i % interiorPerFace_;
    for (uint64_t j = 1;; ++j) {  // rows of interior points: j = 1 .. s-2, i = 1 .. s-1-j
      const uint64_t row = s_ - 1 - j;
      if (k < row) return latticePosition(f, k + 1, j);
      k -= row;
    }
  }
  Tri triangle(uint64_t t) const override {
    const uint64_t f = t / (s_ * s_);
    uint64_t local = t % (s_ * s_);
    for (uint64_t j = 0;; ++j) {  // row j holds s-j upward and s-j-1 downward triangles
      const uint64_t row = 2 * (s_ - j) - 1;
      if (local < row) {
        const uint64_t i = local / 2;
        if (local % 2 == 0) return Tri{{latticeId(f, i, j), latticeId(f, i + 1, j), latticeId(f, i, j + 1)}};
        return Tri{{latticeId(f, i + 1, j), latticeId(f, i + 1, j + 1), latticeId(f, i, j + 1)}};
      }
      local -= row;
    }
  }

 private:
  static uint64_t edgeKey(uint32_t a, uint32_t b) {
    return a < b ? (uint64_t{a} << 32 | b) : (uint64_t{b} << 32 | a);
  }
  glm::dvec3 latticePosition(uint64_t f, uint64_t i, uint64_t j) const {
    const glm::dvec3 a(mesh_.positions[mesh_.indices[3 * f]]), b(mesh_.positions[mesh_.indices[3 * f + 1]]),
        c(mesh_.positions[mesh_.indices[3 * f + 2]]);
    return a + (b - a) * (static_cast<double>(i) / s_) + (c - a) * (static_cast<double>(j) / s_);
  }
  // Id of the point `steps` along the input edge (from, to) of face f, edge slot k.
  uint64_t edgePointId(uint64_t f, int k, uint32_t from, uint64_t steps) const {
    const uint64_t edge = faceEdges_[3 * f + k];
    const uint64_t fromLower = (edges_[edge] >> 32) == from ? steps : s_ - steps;
    return mesh_.positions.size() + edge * (s_ - 1) + (fromLower - 1);
  }
  uint64_t latticeId(uint64_t f, uint64_t i, uint64_t j) const {
    const uint32_t a = mesh_.indices[3 * f], b = mesh_.indices[3 * f + 1], c = mesh_.indices[3 * f + 2];
    if (i == 0 && j == 0) return a;
    if (i == s_) return b;
    if (j == s_) return c;
    if (j == 0) return edgePointId(f, 0, a, i);       // edge a-b
    if (i + j == s_) return edgePointId(f, 1, b, j);  // edge b-c
    if (i == 0) return edgePointId(f, 2, c, s_ - j);  // edge c-a
    uint64_t k = 0;
    for (uint64_t row = 1; row < j; ++row) k += s_ - 1 - row;
    return mesh_.positions.size() + edges_.size() * (s_ - 1) + f * interiorPerFace_ + k + (i - 1);
  }
  MeshView mesh_;
  uint64_t s_;
  std::vector<uint64_t> edges_;      // sorted canonical (lower << 32 | higher) keys
  std::vector<uint64_t> faceEdges_;  // edge id of each face's edge k: (v_k, v_k+1)
  uint64_t interiorPerFace_;
};

GeneratedCounts writeShape(const IndexedShape& shape, const GenerateOptions& options,
                           const std::filesystem::path& path) {
  const uint64_t vertices = shape.vertexCount(), triangles = shape.triangleCount();
  if (vertices > kMaxIndex)
    throw std::invalid_argument("generated mesh would have more than 2^31-1 vertices");
  const StreamPermutation vertexOrder(vertices, options.seed), faceOrder(triangles, options.seed ^ 0xFACE);
  PlyWriter writer(path, vertices, triangles);
  for (uint64_t i = 0; i < vertices; ++i)
    writer.addVertex(glm::vec3(shape.vertex(options.shuffleVertices ? vertexOrder.inverse(i) : i)));
  auto renumber = [&](uint64_t v) {
    return static_cast<uint32_t>(options.shuffleVertices ? vertexOrder.forward(v) : v);
  };
  for (uint64_t j = 0; j < triangles; ++j) {
    const Tri t = shape.triangle(options.shuffleFaces ? faceOrder.inverse(j) : j);
    writer.addTriangle(renumber(t.v[0]), renumber(t.v[1]), renumber(t.v[2]));
  }
  writer.finish();
  return {vertices, triangles};
}

}  // namespace

GeneratedCounts writeSyntheticMesh(SyntheticKind kind, const GenerateOptions& options,
                                   const std::filesystem::path& path) {
  if (options.triangles == 0) throw std::invalid_argument("cannot generate a mesh of 0 triangles");
  switch (kind) {
    case SyntheticKind::Grid:
      return writeShape(
          GridShape(gridSide(options.triangles), gridSide(options.triangles), options.seed, false), options,
          path);
    case SyntheticKind::Terrain:
      return writeShape(
          GridShape(gridSide(options.triangles), gridSide(options.triangles), options.seed, true), options,
          path);
    case SyntheticKind::Strip:
      return writeShape(GridShape(std::max<uint64_t>(1, options.triangles / 2), 1, options.seed, false),
                        options, path);
    case SyntheticKind::Sphere:
      return writeShape(SphereShape(options.triangles), options, path);
    case SyntheticKind::Assembly:
      return writeShape(AssemblyShape(options.triangles), options, path);
    case SyntheticKind::TiledScan:
      return writeShape(TiledScanShape(options.triangles, options.seed), options, path);
  }
  throw std::invalid_argument("unknown synthetic mesh kind");
}

GeneratedCounts writeSubdividedMesh(const MeshView& mesh, unsigned levels, const GenerateOptions& options,
                                    const std::filesystem::path& path) {
  if (levels > 8) throw std::invalid_argument("subdivision levels must be at most 8");
  for (uint32_t index : mesh.indices)
    if (index >= mesh.positions.size())
      throw std::invalid_argument("subdivision input has an index out of range");
  return writeShape(SubdividedShape(mesh, levels), options, path);
}

}  // namespace facetree
