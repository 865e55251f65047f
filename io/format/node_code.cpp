// Version 2 node records (docs/FORMAT.md "Node frames, version 2"): face ranges from the parent's
// record, floats as the merge made them, S and side areas in 12-bit fractions of the area,
// orientations on the stored lattice, exact boxes with half extents rounded up to 18 bits, and
// compact boxes on a grid of 255 steps of the parent box (Ylitie et al. 2017, for oriented boxes).
#include "format/node_code.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include "format/byte_planes.h"
#include "format/fch_format.h"

namespace facetree::fch {
namespace {

constexpr double kSignedFraction = double((1 << (kFractionBits - 1)) - 1);
constexpr double kUnsignedFraction = double((1 << kFractionBits) - 1);
constexpr uint32_t kMaxHalfUnits = (uint32_t{1} << kHalfExtentBits) + 1;

// The smallest float >= v (v finite, within float range).
float roundUp(double v) {
  float f = static_cast<float>(v);
  if (double(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

// The least s with 2^s >= x, x > 0 and normal: from the double's exponent and mantissa bits.
int ceilLog2(double x) {
  const auto bits = std::bit_cast<uint64_t>(x);
  const int e = static_cast<int>((bits >> 52) & 0x7ff) - 1023;
  return (bits & ((uint64_t{1} << 52) - 1)) ? e + 1 : e;
}

// x rounded half away from zero, for |x| < 2^31 (truncation, no library call).
int32_t roundToInt(double x) {
  return static_cast<int32_t>(x + (x < 0 ? -0.5 : 0.5));
}

void axesOf(const glm::quat& q, glm::dvec3 (&axis)[3]) {
  const glm::mat3 m = glm::mat3_cast(q);
  for (int k = 0; k < 3; ++k) axis[k] = glm::dvec3(m[k]);
}

unsigned childNodes(uint8_t shape, uint8_t faceMask) {
  const unsigned children = (shape & 7u) + 2;
  return children - static_cast<unsigned>(std::popcount(static_cast<unsigned>(faceMask)));
}

// A child's axes and the parent box's grid along each: faces at base + q * step, q in 0 ... 255.
struct CompactGrid {
  glm::dvec3 axis[3];
  double base[3], step[3];
};

CompactGrid compactGrid(const NodeBox& parent, const glm::quat& orientation) {
  CompactGrid grid;
  glm::dvec3 parentAxis[3];
  axesOf(orientation, grid.axis);
  axesOf(parent.orientation, parentAxis);
  const glm::dvec3 ph(parent.halfExtent), pc(parent.center);
  // Widened by a little of the parent's size, and by 16 float steps of its coordinates: box
  // centres are floats, so a child's box may leave its parent's by their rounding.
  const double margin = kCompactMargin * (ph.x + ph.y + ph.z) +
                        kCompactCoordinateMargin * (std::abs(pc.x) + std::abs(pc.y) + std::abs(pc.z));
  for (int a = 0; a < 3; ++a) {
    double reach = margin;  // the parent box's half width along axis a, widened
    for (int j = 0; j < 3; ++j) reach += std::abs(glm::dot(grid.axis[a], parentAxis[j])) * ph[j];
    grid.step[a] = 2 * reach / 255;
    grid.base[a] = glm::dot(pc, grid.axis[a]) - reach;
  }
  return grid;
}

// The centre and half extents of the box whose faces are codes lo, hi on `grid`.
void gridBox(const CompactGrid& grid, const uint8_t lo[3], const uint8_t hi[3], NodeBox& box) {
  double l[3], h[3];
  glm::dvec3 mid;
  for (int a = 0; a < 3; ++a) {
    l[a] = grid.base[a] + lo[a] * grid.step[a];
    h[a] = grid.base[a] + hi[a] * grid.step[a];
    mid[a] = 0.5 * (l[a] + h[a]);
  }
  // The float axes are orthonormal only to ~1e-7: solve dot(center, axis_k) = mid_k.
  const glm::dmat3 m(grid.axis[0], grid.axis[1], grid.axis[2]);
  box.center = glm::vec3(glm::inverse(glm::transpose(m)) * mid);
  const glm::dvec3 c(box.center);
  for (int a = 0; a < 3; ++a) {
    const double ca = glm::dot(c, grid.axis[a]);
    const double half = std::max({h[a] - ca, ca - l[a], 0.0});
    box.halfExtent[a] = roundUp(half + 0x1p-40 * (std::abs(ca) + half));
  }
}

}  // namespace

void compactStep(const NodeBox& parent, const glm::quat& orientation, double step[3]) {
  const CompactGrid grid = compactGrid(parent, orientation);
  for (int a = 0; a < 3; ++a) step[a] = grid.step[a];
}

void compactBox(const NodeBox& parent, const glm::quat& orientation, const uint8_t lo[3], const uint8_t hi[3],
                NodeBox& box) {
  gridBox(compactGrid(parent, orientation), lo, hi, box);
  box.orientation = orientation;
}

namespace {

// quantizeNode with the orientation on a lattice of `bits` and the box coded as `precision` says.
NodeCode quantizeRecord(const FchNode& node, uint64_t index, unsigned bits, BoxPrecision precision,
                        const NodeBox* parent, NodeBox* decoded) {
  const auto fail = [&](const std::string& why) {
    throw std::invalid_argument("node " + std::to_string(index) + ": " + why);
  };
  NodeCode code;
  if (node.childCount < 2 || node.childCount > kMaxBranching)
    fail(std::to_string(node.childCount) + " children");
  const NodeBox& box = node.box;
  const OrientationCode orientation = encodeOrientation(box.orientation, bits);
  const glm::quat lattice = decodeOrientation(orientation, bits);
  if (!(lattice == box.orientation))
    fail("box orientation off the stored lattice (build with the file's BuildOptions::boxes)");
  code.shape = static_cast<uint8_t>((node.childCount - 2) | (node.flags & kStoredFlagMask) << 3 |
                                    orientation.largest << 5);

  // Children: the node child with most faces (the first of equals) is the derived one.
  int derived = -1;
  uint64_t faces = 0;
  for (unsigned c = 0; c < node.childCount; ++c) {
    if (node.child[c] & kFaceChild) {
      code.faceMask |= static_cast<uint8_t>(1u << c);
      faces += 1;
      continue;
    }
    if (node.childFaces[c] < 2) fail("node child " + std::to_string(c) + " of fewer than 2 faces");
    faces += node.childFaces[c];
    if (derived < 0 || node.childFaces[c] > node.childFaces[derived]) derived = static_cast<int>(c);
  }
  if (faces != node.count)
    fail("its children's face counts add up to " + std::to_string(faces) + ", not its " +
         std::to_string(node.count) + " faces");
  code.derived = static_cast<uint8_t>(std::max(derived, 0));
  for (unsigned c = 0; c < node.childCount; ++c) {
    if (node.child[c] & kFaceChild) continue;
    code.ref[code.refCount++] = static_cast<uint32_t>(node.child[c] - index);
    if (static_cast<int>(c) != derived) code.faces[code.faceCountCount++] = node.childFaces[c];
  }

  code.cost = node.cost;
  code.area = node.area;
  code.perimeter = node.perimeter;
  const double area = node.area;
  const double perArea = area > 0 && std::isfinite(area) ? 1.0 / area : 0.0;
  for (int a = 0; a < 3; ++a) {
    const double s =
        std::clamp(node.sumNormal[a] * perArea * kSignedFraction, -kSignedFraction, kSignedFraction);
    code.sumNormal[a] = static_cast<uint16_t>(zigzag32(roundToInt(s)));
    const double sum = double(box.sideArea[2 * a]) + box.sideArea[2 * a + 1];
    code.sideSum[a] = static_cast<uint16_t>(
        roundToInt(std::clamp(sum * perArea * kUnsignedFraction, 0.0, kUnsignedFraction)));
  }
  for (int k = 0; k < 3; ++k) code.orientation[k] = static_cast<uint16_t>(zigzag32(orientation.component[k]));

  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(box.center[a]) || !std::isfinite(box.halfExtent[a]) || box.halfExtent[a] < 0)
      fail("box not finite");
  if (precision == BoxPrecision::Compact && !parent) {  // the root: its box goes in the header
    if (decoded) *decoded = box;
    return code;
  }
  if (precision == BoxPrecision::Exact) {
    const double largest = std::max({box.halfExtent.x, box.halfExtent.y, box.halfExtent.z});
    const int scale = largest > 0 ? std::max(ceilLog2(largest), kMinScale) : kMinScale;
    if (scale > kMaxScale) fail("box too large");
    // Units of a power of two: the division is exact, and the quotient at most 2^18.
    const double perUnit = std::bit_cast<double>(uint64_t(1023 - (scale - kHalfExtentBits)) << 52);
    code.scale = static_cast<uint8_t>(scale + kScaleBias);
    for (int a = 0; a < 3; ++a) {
      code.center[a] = box.center[a];
      const double units = box.halfExtent[a] * perUnit;
      code.half[a] = static_cast<uint32_t>(units);
      if (code.half[a] < units) ++code.half[a];
    }
    if (decoded) *decoded = box;
    return code;
  }

  const NodeBox out = quantizeCompactBox(box, *parent, index, code);
  if (decoded) *decoded = out;
  return code;
}

}  // namespace

NodeBox quantizeCompactBox(const NodeBox& box, const NodeBox& parent, uint64_t index, NodeCode& code) {
  const CompactGrid grid = compactGrid(parent, box.orientation);
  const glm::dvec3 c(box.center);
  double lo[3] = {}, hi[3] = {};
  for (int a = 0; a < 3; ++a) {
    const double ca = glm::dot(c, grid.axis[a]);
    const double slack = 0x1p-40 * (std::abs(ca) + box.halfExtent[a]);
    lo[a] = ca - box.halfExtent[a] - slack;
    hi[a] = ca + box.halfExtent[a] + slack;
    const double qlo = std::floor((lo[a] - grid.base[a]) / grid.step[a]);
    const double qhi = std::ceil((hi[a] - grid.base[a]) / grid.step[a]);
    if (!(qlo >= 0 && qhi <= 255 && grid.step[a] > 0))
      throw std::logic_error("node " + std::to_string(index) + ": box outside its parent's (compact boxes)");
    code.lo[a] = static_cast<uint8_t>(qlo);
    code.hi[a] = static_cast<uint8_t>(qhi);
  }
  // The decoded box must hold the exact one: widen by a step where rounding says otherwise.
  NodeBox out;
  out.orientation = box.orientation;
  for (int attempt = 0;; ++attempt) {
    gridBox(grid, code.lo, code.hi, out);
    bool holds = true;
    const glm::dvec3 oc(out.center);
    for (int a = 0; a < 3; ++a) {
      const double ca = glm::dot(oc, grid.axis[a]);
      if (ca - out.halfExtent[a] > lo[a]) {
        holds = false;
        if (code.lo[a] == 0 || attempt == 4)
          throw std::logic_error("node " + std::to_string(index) + ": compact box cannot hold it");
        --code.lo[a];
      }
      if (ca + out.halfExtent[a] < hi[a]) {
        holds = false;
        if (code.hi[a] == 255 || attempt == 4)
          throw std::logic_error("node " + std::to_string(index) + ": compact box cannot hold it");
        ++code.hi[a];
      }
    }
    if (holds) break;
  }
  return out;
}

NodeCode quantizeNode(const FchNode& node, uint64_t index, BoxPrecision precision, const NodeBox* parent,
                      NodeBox* decoded) {
  return quantizeRecord(node, index, orientationBits(precision), precision, parent, decoded);
}

NodeCode quantizeRunNode(const FchNode& node, uint64_t index, BoxPrecision precision) {
  return quantizeRecord(node, index, orientationBits(precision), BoxPrecision::Exact, nullptr, nullptr);
}

std::string encodeNodeFrame(std::span<const NodeCode> codes, BoxPrecision precision) {
  std::string out;
  encodeNodeFrame(codes, precision, out);
  return out;
}

void encodeNodeFrame(std::span<const NodeCode> codes, BoxPrecision precision, std::string& out) {
  const size_t n = codes.size();
  size_t refs = 0, counts = 0;
  for (const NodeCode& c : codes) refs += c.refCount, counts += c.faceCountCount;
  out.clear();
  out.reserve(nodeFixedBytes(precision) * n + 4 * (refs + counts));
  // The next column, of `width` bytes an element, from each code's `get`.
  const auto column = [&](unsigned width, auto get) {
    putColumn(
        out, n, [&](size_t i) -> uint64_t { return get(codes[i]); }, width);
  };
  column(1, [](const NodeCode& c) { return c.shape; });
  column(1, [](const NodeCode& c) { return c.faceMask; });
  column(1, [](const NodeCode& c) { return c.derived; });
  column(4, [](const NodeCode& c) { return bits(c.cost); });
  column(4, [](const NodeCode& c) { return bits(c.area); });
  column(4, [](const NodeCode& c) { return bits(c.perimeter); });
  for (int a = 0; a < 3; ++a) column(2, [a](const NodeCode& c) { return c.sumNormal[a]; });
  for (int a = 0; a < 3; ++a) column(2, [a](const NodeCode& c) { return c.sideSum[a]; });
  const unsigned orientationWidth = precision == BoxPrecision::Compact ? 1 : 2;
  for (int k = 0; k < 3; ++k) column(orientationWidth, [k](const NodeCode& c) { return c.orientation[k]; });
  if (precision == BoxPrecision::Compact) {
    for (int a = 0; a < 3; ++a) column(1, [a](const NodeCode& c) { return c.lo[a]; });
    for (int a = 0; a < 3; ++a) column(1, [a](const NodeCode& c) { return c.hi[a]; });
  } else {
    column(1, [](const NodeCode& c) { return c.scale; });
    for (int a = 0; a < 3; ++a) column(4, [a](const NodeCode& c) { return bits(c.center[a]); });
    for (int a = 0; a < 3; ++a) column(3, [a](const NodeCode& c) { return c.half[a]; });
  }
  std::vector<uint32_t> lists;  // the refs, then the face counts, of every code in turn
  lists.reserve(std::max(refs, counts));
  for (const NodeCode& c : codes) lists.insert(lists.end(), c.ref, c.ref + c.refCount);
  putColumn(out, lists.size(), [&](size_t i) { return lists[i]; });
  lists.clear();
  for (const NodeCode& c : codes) lists.insert(lists.end(), c.faces, c.faces + c.faceCountCount);
  putColumn(out, lists.size(), [&](size_t i) { return lists[i]; });
}

std::string decodeNodeFrame(std::string_view raw, size_t n, BoxPrecision precision, unsigned branching,
                            std::vector<NodeCode>& out, bool structure) {
  const uint32_t fixed = nodeFixedBytes(precision);
  if (raw.size() < uint64_t{fixed} * n) return "payload smaller than its nodes' fixed fields";
  const auto* p = reinterpret_cast<const uint8_t*>(raw.data());
  const uint8_t *shape = p, *faceMask = p + n, *derived = p + 2 * n;
  uint64_t refs = 0, counts = 0;
  for (size_t i = 0; i < n; ++i) {
    const unsigned children = (shape[i] & 7u) + 2;
    if (children > branching || (shape[i] & 0x80))
      return "node " + std::to_string(i) + " of the frame: bad shape byte " + std::to_string(shape[i]);
    if (faceMask[i] >> children)
      return "node " + std::to_string(i) + " of the frame: face mask beyond its children";
    const unsigned nodes = childNodes(shape[i], faceMask[i]);
    if (derived[i] >= children || (nodes > 0 && (faceMask[i] >> derived[i] & 1)))
      return "node " + std::to_string(i) + " of the frame: bad derived child " + std::to_string(derived[i]);
    refs += nodes;
    counts += nodes ? nodes - 1 : 0;
  }
  if (raw.size() != uint64_t{fixed} * n + 4 * (refs + counts))
    return "payload size disagrees with the child counts";
  const size_t base = out.size();
  out.resize(base + n);
  NodeCode* codes = out.data() + base;
  Columns col(raw);
  // The next column, of `width` bytes an element, given to `set` with each code.
  const auto column = [&](unsigned width, auto set) {
    col.next(n, width);
    for (size_t i = 0; i < n; ++i) set(codes[i], col.at(i));
  };
  // S, side areas and boxes: passed over when only the tree is asked for.
  const auto boxColumn = [&](unsigned width, auto set) {
    if (structure)
      col.next(n, width);
    else
      column(width, set);
  };
  const auto f32 = [](uint64_t v) { return std::bit_cast<float>(static_cast<uint32_t>(v)); };
  column(1, [](NodeCode& c, uint64_t v) { c.shape = static_cast<uint8_t>(v); });
  column(1, [](NodeCode& c, uint64_t v) { c.faceMask = static_cast<uint8_t>(v); });
  column(1, [](NodeCode& c, uint64_t v) { c.derived = static_cast<uint8_t>(v); });
  column(4, [&](NodeCode& c, uint64_t v) { c.cost = f32(v); });
  column(4, [&](NodeCode& c, uint64_t v) { c.area = f32(v); });
  column(4, [&](NodeCode& c, uint64_t v) { c.perimeter = f32(v); });
  for (int a = 0; a < 3; ++a)
    boxColumn(2, [a](NodeCode& c, uint64_t v) { c.sumNormal[a] = static_cast<uint16_t>(v); });
  for (int a = 0; a < 3; ++a)
    boxColumn(2, [a](NodeCode& c, uint64_t v) { c.sideSum[a] = static_cast<uint16_t>(v); });
  const unsigned orientationWidth = precision == BoxPrecision::Compact ? 1 : 2;
  for (int k = 0; k < 3; ++k)
    boxColumn(orientationWidth,
              [k](NodeCode& c, uint64_t v) { c.orientation[k] = static_cast<uint16_t>(v); });
  if (precision == BoxPrecision::Compact) {
    for (int a = 0; a < 3; ++a)
      boxColumn(1, [a](NodeCode& c, uint64_t v) { c.lo[a] = static_cast<uint8_t>(v); });
    for (int a = 0; a < 3; ++a)
      boxColumn(1, [a](NodeCode& c, uint64_t v) { c.hi[a] = static_cast<uint8_t>(v); });
  } else {
    boxColumn(1, [](NodeCode& c, uint64_t v) { c.scale = static_cast<uint8_t>(v); });
    for (int a = 0; a < 3; ++a) boxColumn(4, [&, a](NodeCode& c, uint64_t v) { c.center[a] = f32(v); });
    for (int a = 0; a < 3; ++a)
      boxColumn(3, [a](NodeCode& c, uint64_t v) { c.half[a] = static_cast<uint32_t>(v); });
  }
  col.next(refs);
  size_t r = 0;
  for (size_t i = 0; i < n; ++i) {
    codes[i].refCount = static_cast<uint8_t>(childNodes(codes[i].shape, codes[i].faceMask));
    for (unsigned k = 0; k < codes[i].refCount; ++k) codes[i].ref[k] = static_cast<uint32_t>(col.at(r++));
  }
  col.next(counts);
  r = 0;
  for (size_t i = 0; i < n; ++i) {
    codes[i].faceCountCount = static_cast<uint8_t>(codes[i].refCount ? codes[i].refCount - 1 : 0);
    for (unsigned k = 0; k < codes[i].faceCountCount; ++k)
      codes[i].faces[k] = static_cast<uint32_t>(col.at(r++));
  }
  return {};
}

namespace {

// The orientation a record's code gives, on a lattice of `bits`; an empty string, or why it is invalid.
std::string decodeOrientationOf(const NodeCode& code, unsigned bits, glm::quat& orientation) {
  OrientationCode stored;
  stored.largest = static_cast<uint8_t>((code.shape >> 5) & 3);
  for (int k = 0; k < 3; ++k) stored.component[k] = unzigzag32(code.orientation[k]);
  const int32_t limit = (int32_t{1} << (bits - 1)) - 1;
  for (int32_t c : stored.component)
    if (c < -limit || c > limit) return "orientation component " + std::to_string(c) + " out of range";
  orientation = decodeOrientation(stored, bits);
  return {};
}

// An exact box's centre and half extents from its record (the orientation is the caller's).
std::string decodeExactBox(const NodeCode& code, NodeBox& box) {
  const int scale = int(code.scale) - kScaleBias;
  if (scale < kMinScale || scale > kMaxScale)
    return "box scale " + std::to_string(code.scale) + " out of range";
  const double unit = std::ldexp(1.0, scale - kHalfExtentBits);
  for (int a = 0; a < 3; ++a) {
    if (code.half[a] > kMaxHalfUnits || !std::isfinite(code.center[a])) return "box out of range";
    box.center[a] = code.center[a];
    box.halfExtent[a] = static_cast<float>(code.half[a] * unit);
    if (!std::isfinite(box.halfExtent[a])) return "box out of range";
  }
  return {};
}

// The node `index` of faces first ... first + count - 1 that `code` holds, with its box's centre and
// extents when `exactBox` (else left for the caller); orientation on a lattice of `bits`. Returns
// an empty string, or why the record is invalid.
std::string decodeRecord(const NodeCode& code, uint64_t index, uint32_t first, uint32_t count, unsigned bits,
                         bool exactBox, bool structure, FchNode& node) {
  node = FchNode{};
  node.first = first;
  node.count = count;
  node.childCount = static_cast<uint8_t>((code.shape & 7u) + 2);
  node.flags = static_cast<uint8_t>((code.shape >> 3) & kStoredFlagMask);

  // Face counts: the stored ones, and the derived child's from the node's own.
  uint64_t known = 0;
  unsigned stored = 0;
  for (unsigned c = 0; c < node.childCount; ++c) {
    if (code.faceMask >> c & 1) {
      known += 1;
    } else if (c != code.derived) {
      const uint32_t faces = code.faces[stored++];
      if (faces < 2) return "child " + std::to_string(c) + " of " + std::to_string(faces) + " faces";
      known += faces;
    }
  }
  const bool anyNode = code.refCount > 0;
  if (anyNode ? known + 2 > node.count : known != node.count)
    return "children's face counts (" + std::to_string(known) + " besides the derived one) do not fit its " +
           std::to_string(node.count) + " faces";
  uint32_t cursor = node.first;
  unsigned ref = 0;
  stored = 0;
  for (unsigned c = 0; c < node.childCount; ++c) {
    if (code.faceMask >> c & 1) {
      node.child[c] = kFaceChild | cursor;
      node.childFaces[c] = 1;
      cursor += 1;
      continue;
    }
    const uint64_t target = index + code.ref[ref++];
    if (target == index || target >= kFaceChild) return "bad child reference";
    const uint32_t faces =
        c == code.derived ? static_cast<uint32_t>(node.count - known) : code.faces[stored++];
    node.child[c] = static_cast<uint32_t>(target);
    node.childFaces[c] = faces;
    cursor += faces;
  }

  if (!std::isfinite(code.cost) || !std::isfinite(code.area) || !std::isfinite(code.perimeter))
    return "cost, area or perimeter not finite";
  node.cost = code.cost;
  node.area = code.area;
  node.perimeter = code.perimeter;
  if (structure) return {};
  NodeBox& box = node.box;
  if (std::string error = decodeOrientationOf(code, bits, box.orientation); !error.empty()) return error;
  glm::dvec3 axis[3];
  axesOf(box.orientation, axis);
  const double area = node.area;
  glm::dvec3 s;
  for (int a = 0; a < 3; ++a) {
    const int32_t q = unzigzag32(code.sumNormal[a]);
    if (q < -int32_t(kSignedFraction) || q > int32_t(kSignedFraction) || code.sideSum[a] > kUnsignedFraction)
      return "S or side area fraction out of range";
    s[a] = q / kSignedFraction * area;
    node.sumNormal[a] = static_cast<float>(s[a]);
  }
  for (int a = 0; a < 3; ++a) {
    const double sum = code.sideSum[a] / kUnsignedFraction * area, along = glm::dot(s, axis[a]);
    box.sideArea[2 * a] = static_cast<float>(std::max(0.0, 0.5 * (sum + along)));
    box.sideArea[2 * a + 1] = static_cast<float>(std::max(0.0, 0.5 * (sum - along)));
  }
  if (!exactBox) return {};
  return decodeExactBox(code, box);
}

}  // namespace

std::string compactRunRecord(NodeCode& code, uint64_t index, const NodeBox* parent, NodeBox& decoded) {
  NodeBox box;
  if (std::string error = decodeOrientationOf(code, orientationBits(BoxPrecision::Compact), box.orientation);
      !error.empty())
    return error;
  if (std::string error = decodeExactBox(code, box); !error.empty()) return error;
  if (!parent) {  // the root: its box goes in the header
    decoded = box;
    return {};
  }
  try {
    decoded = quantizeCompactBox(box, *parent, index, code);
  } catch (const std::logic_error& e) {
    return e.what();
  }
  return {};
}

void decodeNodeCodes(const SourceFile& file, size_t i, const std::string& raw, std::vector<NodeCode>& out,
                     bool structure) {
  const FchLayout& layout = file.layout();
  const std::string error = decodeNodeFrame(raw, layout.frames[i].count, layout.header.boxes,
                                            layout.header.branching, out, structure);
  if (!error.empty()) file.fail(file.where(i) + ": " + error);
}

NodeDecoder::NodeDecoder(const FileHeader& header, const NodeBox& rootBox, uint32_t nodesPerFrame,
                         uint64_t budget, const std::filesystem::path& tmp, bool structure)
    : header_(header),
      rootBox_(rootBox),
      nodesPerFrame_(nodesPerFrame),
      // A parent's box (48 bytes) goes with each announced child (20 bytes) when boxes are decoded.
      frontier_(nodesPerFrame, header.boxes == BoxPrecision::Compact && !structure ? budget / 3 : budget,
                tmp),
      boxes_(nodesPerFrame, budget - budget / 3, tmp),
      structure_(structure) {}

std::string decodeNodeAt(const FileHeader& header, const NodeBox& rootBox, const NodeCode& code,
                         uint64_t index, const PendingChild& range, const NodeBox* parentBox, bool structure,
                         FchNode& node) {
  const bool compact = header.boxes == BoxPrecision::Compact && !structure;
  if (std::string error = decodeRecord(code, index, range.first, range.count, orientationBits(header.boxes),
                                       !compact, structure, node);
      !error.empty())
    return error;
  if (compact) {
    NodeBox& box = node.box;
    for (int a = 0; a < 3; ++a)
      if (code.lo[a] > code.hi[a]) return "compact box face below its opposite";
    if (index == 0) {
      box.center = rootBox.center;
      box.halfExtent = rootBox.halfExtent;
    } else {
      if (!parentBox) return "no earlier node refers to it";
      compactBox(*parentBox, box.orientation, code.lo, code.hi, box);
    }
  }
  for (unsigned c = 0; c < node.childCount; ++c)
    if (!(node.child[c] & kFaceChild) && node.child[c] >= header.nodeCount) node.flags |= kFchTruncated;
  return {};
}

std::string NodeDecoder::decode(const NodeCode& code, uint64_t index, FchNode& node, uint32_t& depth) {
  if (index != next_) return "decoded out of order";
  ++next_;
  const uint64_t frame = index / nodesPerFrame_;
  if (index % nodesPerFrame_ == 0 || frame != frame_) {
    frame_ = frame;
    const uint64_t frameFirst = frame * nodesPerFrame_;
    const auto count =
        static_cast<uint32_t>(std::min<uint64_t>(nodesPerFrame_, header_.nodeCount - frameFirst));
    slots_ = &frontier_.take(frame, count);
    if (compact()) boxSlots_ = &boxes_.take(frame, count);
  }
  PendingChild range{0, static_cast<uint32_t>(header_.triangleCount), 1, 0, 0};
  NodeBox parentBox{};
  if (index > 0) {
    const PendingChild& slot = (*slots_)[index % nodesPerFrame_];
    if (slot.depth == 0) return "no earlier node refers to it";
    if (slot.depth == kAnnouncedTwice) return "child " + std::to_string(index) + " of two nodes";
    range = slot;
    if (compact()) {
      const PendingParentBox& box = (*boxSlots_)[index % nodesPerFrame_];
      parentBox.center = box.center, parentBox.halfExtent = box.halfExtent;
      parentBox.orientation = box.orientation;
    }
  }
  depth = range.depth;
  if (std::string error = decodeNodeAt(header_, rootBox_, code, index, range,
                                       compact() && index > 0 ? &parentBox : nullptr, structure_, node);
      !error.empty())
    return error;
  // The node children this record announces, with their face ranges (and, for compact boxes,
  // this node's box, which theirs are quantised against).
  uint32_t cursor = node.first;
  for (unsigned c = 0; c < node.childCount; ++c) {
    const uint32_t child = node.child[c];
    if (!(child & kFaceChild) && child < header_.nodeCount) {
      frontier_.announce(
          child, PendingChild{cursor, node.childFaces[c], depth + 1, static_cast<uint32_t>(index), 0});
      if (compact())
        boxes_.announce(child, PendingParentBox{node.box.center, node.box.halfExtent, node.box.orientation,
                                                depth + 1, 0});
    }
    cursor += node.childFaces[c];
  }
  return {};
}

uint64_t NodeDecoder::heldBytes() const {
  return frontier_.heldBytes() + boxes_.heldBytes();
}

uint64_t NodeDecoder::spilledBytes() const {
  return frontier_.spilledBytes() + boxes_.spilledBytes();
}

}  // namespace facetree::fch
