// facetree.open: a cluster file read lazily under a memory cap (ClusterFileReader), for the next
// stage of a pipeline: nodes as a structured array, cuts, and the triangles of a node or a face
// range, decoding only what is asked, with the GIL released while it decodes.
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>

#include <pybind11/stl.h>

#include "bindings.h"
#include "facetree/query.h"

namespace facetree::python {
namespace {

// One node as facetree.open's nodes() gives it (NODE_DTYPE in the docstring).
struct NodeRecord {
  uint32_t first, count;
  uint8_t child_count, flags;
  int64_t children[kMaxBranching];  // node index, -1 for a face, a cut-off child or an empty slot
  uint32_t child_faces[kMaxBranching];
  float cost, area, perimeter;
  float sum_normal[3];
  float box_center[3], box_half_extents[3], box_orientation[4], box_side_areas[6];
};

struct PyReader {
  std::filesystem::path path;
  std::unique_ptr<ClusterFileReader> reader;
  std::unique_ptr<ReaderQueryIndex> index;  // built by the first query, kept for the next ones

  ClusterFileReader& open() {
    if (!reader) throw ArgumentError(path.string() + ": the reader is closed");
    return *reader;
  }
  // The reader's query index (a pass over the nodes the first time): called with the GIL released.
  ReaderQueryIndex& queries() {
    if (!index) index = std::make_unique<ReaderQueryIndex>(open());
    return *index;
  }
  void close() {
    index.reset();
    reader.reset();
  }
};

NodeRecord record(const FchNode& node, uint64_t nodeCount) {
  NodeRecord r{};
  r.first = node.first, r.count = node.count, r.child_count = node.childCount, r.flags = node.flags;
  for (unsigned c = 0; c < kMaxBranching; ++c) {
    const bool used = c < node.childCount;
    const uint32_t ref = node.child[c];
    r.children[c] = used && !(ref & kFaceChild) && ref < nodeCount ? int64_t{ref} : -1;
    r.child_faces[c] = used ? node.childFaces[c] : 0;
  }
  r.cost = node.cost, r.area = node.area, r.perimeter = node.perimeter;
  const NodeBox& box = node.box;
  for (int a = 0; a < 3; ++a) {
    r.sum_normal[a] = node.sumNormal[a];
    r.box_center[a] = box.center[a];
    r.box_half_extents[a] = box.halfExtent[a];
  }
  const float q[4] = {box.orientation.x, box.orientation.y, box.orientation.z, box.orientation.w};
  std::copy(q, q + 4, r.box_orientation);
  std::copy(box.sideArea, box.sideArea + 6, r.box_side_areas);
  return r;
}

// (N, 3) origins and directions with a t range (t_max a number or an (N,) array), checked.
struct RayArrays {
  using Floats = py::array_t<float, py::array::c_style | py::array::forcecast>;
  Floats o, d, t;
  bool hasTMax = false;
  size_t n = 0;
  float tMin = 0.0f;
  RayArrays(const py::object& origins, const py::object& directions, const py::object& tMax, float tMin)
      : o(Floats::ensure(origins)), d(Floats::ensure(directions)), tMin(tMin) {
    if (!o || o.ndim() != 2 || o.shape(1) != 3) throw ArgumentError("origins: expected an (N, 3) array");
    if (!d || d.ndim() != 2 || d.shape(1) != 3 || d.shape(0) != o.shape(0))
      throw ArgumentError("directions: expected an (N, 3) array, as many as the origins");
    n = static_cast<size_t>(o.shape(0));
    if (!tMax.is_none()) {
      hasTMax = true;
      t = Floats::ensure(tMax);
      if (!t || (t.ndim() != 0 && (t.ndim() != 1 || static_cast<size_t>(t.shape(0)) != n)))
        throw ArgumentError("t_max: expected a number or an (N,) array");
    }
  }
  // Rays [first, first + rays.size()).
  void fill(size_t first, std::vector<Ray>& rays) const {
    const float *op = o.data(), *dp = d.data();
    for (size_t k = 0; k < rays.size(); ++k) {
      const size_t i = first + k;
      rays[k].origin = {op[3 * i], op[3 * i + 1], op[3 * i + 2]};
      rays[k].direction = {dp[3 * i], dp[3 * i + 1], dp[3 * i + 2]};
      rays[k].tMin = tMin;
      if (hasTMax) rays[k].tMax = t.ndim() == 0 ? t.data()[0] : t.data()[i];
    }
  }
};

// The rays cast by query(reader, rays) with the GIL released, a chunk at a time, each chunk's
// results handed to store(first, results): the arrays a caller gets are written once, and what a
// chunk holds stays in the caches (a million rays' hits at once cost more in page faults than the
// traversal of a file in memory).
template <class Query, class Store>
void castRays(PyReader& r, const RayArrays& arrays, Query&& query, Store&& store) {
  constexpr size_t kChunk = 1 << 16;
  r.open();
  py::gil_scoped_release release;
  std::vector<Ray> rays;
  for (size_t first = 0; first < arrays.n; first += kChunk) {
    rays.resize(std::min(kChunk, arrays.n - first));
    arrays.fill(first, rays);
    store(first, query(r.queries(), rays));
  }
}

py::tuple meshTuple(FaceRangeMesh&& mesh) {
  const auto vertices = static_cast<py::ssize_t>(mesh.vertices.size());
  const auto triangles = static_cast<py::ssize_t>(mesh.originalFace.size());
  std::vector<float> positions(3 * mesh.vertices.size());
  for (size_t v = 0; v < mesh.vertices.size(); ++v)
    for (int a = 0; a < 3; ++a) positions[3 * v + a] = mesh.vertices[v][a];
  return py::make_tuple(arrayOwning(std::move(positions), {vertices, 3}),
                        arrayOwning(std::move(mesh.indices), {triangles, 3}),
                        arrayOwning(std::move(mesh.originalFace), {triangles}));
}

using Floats = py::array_t<float, py::array::c_style | py::array::forcecast>;

// The triangles overlapping each box, with the GIL released: (offsets, faces) arrays.
py::tuple overlapTuple(PyReader& r, const std::vector<QueryBox>& boxes, unsigned threads) {
  r.open();
  std::vector<std::vector<uint64_t>> found;
  {
    py::gil_scoped_release release;
    found = overlap(r.queries(), boxes, {threads});
  }
  std::vector<int64_t> offsets(found.size() + 1, 0);
  for (size_t i = 0; i < found.size(); ++i)
    offsets[i + 1] = offsets[i] + static_cast<int64_t>(found[i].size());
  std::vector<int64_t> faces(static_cast<size_t>(offsets.back()));
  for (size_t i = 0; i < found.size(); ++i)
    std::copy(found[i].begin(), found[i].end(), faces.begin() + offsets[i]);
  const auto n = static_cast<py::ssize_t>(offsets.size()), m = static_cast<py::ssize_t>(faces.size());
  return py::make_tuple(arrayOwning(std::move(offsets), {n}), arrayOwning(std::move(faces), {m}));
}

// Oriented boxes from centres, half extents and rotation matrices whose columns are the axes. A
// matrix that is not a rotation (orthonormal columns, determinant +1, within 1e-4) is refused:
// its quaternion would silently describe another box.
std::vector<QueryBox> orientedBoxes(const py::object& centers, const py::object& halfExtents,
                                    const py::object& axes) {
  const Floats c = Floats::ensure(centers), h = Floats::ensure(halfExtents), a = Floats::ensure(axes);
  if (!c || c.ndim() != 2 || c.shape(1) != 3)
    throw ArgumentError("overlap_oriented: centers must be an (N, 3) array");
  if (!h || h.ndim() != 2 || h.shape(1) != 3 || h.shape(0) != c.shape(0))
    throw ArgumentError("overlap_oriented: half_extents must be an (N, 3) array, as many as the centers");
  if (!a || a.ndim() != 3 || a.shape(1) != 3 || a.shape(2) != 3 || a.shape(0) != c.shape(0))
    throw ArgumentError("overlap_oriented: axes must be an (N, 3, 3) array, as many as the centers");
  constexpr double kRotationTolerance = 1e-4;
  std::vector<QueryBox> boxes(static_cast<size_t>(c.shape(0)));
  for (size_t i = 0; i < boxes.size(); ++i) {
    glm::mat3 m;
    for (int row = 0; row < 3; ++row)
      for (int col = 0; col < 3; ++col) m[col][row] = a.data()[9 * i + 3 * row + col];
    const glm::dmat3 d(m);
    const glm::dmat3 g = glm::transpose(d) * d;
    double worst = std::abs(glm::determinant(d) - 1.0);
    for (int x = 0; x < 3; ++x)
      for (int y = 0; y < 3; ++y) worst = std::max(worst, std::abs(g[x][y] - (x == y ? 1.0 : 0.0)));
    if (!(worst <= kRotationTolerance))
      throw ArgumentError("overlap_oriented: axes[" + std::to_string(i) +
                          "] is not a rotation (orthonormal columns, determinant 1)");
    for (int k = 0; k < 3; ++k) {
      const float e = h.data()[3 * i + k];
      if (!(e >= 0.0f) || !std::isfinite(e))
        throw ArgumentError("overlap_oriented: half_extents[" + std::to_string(i) +
                            "] must be finite and >= 0");
    }
    boxes[i].center = {c.data()[3 * i], c.data()[3 * i + 1], c.data()[3 * i + 2]};
    boxes[i].halfExtent = {h.data()[3 * i], h.data()[3 * i + 1], h.data()[3 * i + 2]};
    boxes[i].orientation = glm::normalize(glm::quat_cast(m));
  }
  return boxes;
}

}  // namespace

void registerReader(py::module_& m) {
  PYBIND11_NUMPY_DTYPE(NodeRecord, first, count, child_count, flags, children, child_faces, cost, area,
                       perimeter, sum_normal, box_center, box_half_extents, box_orientation, box_side_areas);
  py::class_<PyReader> c(m, "Reader", R"(A cluster file read lazily under a memory cap (facetree.open).

Opening reads the header and the frame index only; nodes and triangles are decoded frame by frame
as they are asked for, every frame checked first. Use it as a context manager, or call close().)");
  c.def("__len__", [](PyReader& r) { return r.open().size(); })
      .def("__enter__", [](py::object self) { return self; })
      .def("__exit__", [](PyReader& r, py::args) { r.close(); })
      .def(
          "close", [](PyReader& r) { r.close(); }, "Releases the file and what the reader holds.")
      .def_property_readonly("closed", [](const PyReader& r) { return !r.reader; })
      .def_property_readonly(
          "header", [](PyReader& r) { return headerDict(r.open().header()); },
          "The file header: counts and the options the hierarchy was built with.")
      .def(
          "nodes",
          [](PyReader& r, uint64_t start, std::optional<uint64_t> stop) {
            ClusterFileReader& reader = r.open();
            const uint64_t end = std::min(stop.value_or(reader.size()), reader.size());
            const uint64_t first = std::min(start, end);
            py::array_t<NodeRecord> out(static_cast<py::ssize_t>(end - first));
            NodeRecord* records = out.mutable_data();
            {
              py::gil_scoped_release release;
              for (uint64_t i = first; i < end; ++i)
                records[i - first] = record(reader.node(i), reader.size());
            }
            return out;
          },
          py::arg("start") = 0, py::arg("stop") = py::none(),
          R"(Nodes [start, stop) as a NumPy structured array: first and count (the face range), child_count,
flags, children (8 slots: node index, -1 for a face, a child cut off by truncation or an empty slot),
child_faces, cost, area, perimeter, sum_normal, and the oriented box: box_center, box_half_extents,
box_orientation (quaternion x, y, z, w) and box_side_areas. Nodes decode in file order: a slice far
into the file decodes the frames before it once.)")
      .def(
          "cut",
          [](PyReader& r, std::optional<uint64_t> clusters, std::optional<double> maxCost,
             std::optional<uint32_t> depth) {
            ClusterFileReader& reader = r.open();
            if (int{clusters.has_value()} + int{maxCost.has_value()} + int{depth.has_value()} != 1)
              throw ArgumentError("cut needs exactly one of clusters, max_cost and depth");
            if (clusters && *clusters == 0) throw ArgumentError("clusters must be at least 1");
            std::vector<CutCluster> cut;
            {
              py::gil_scoped_release release;
              cut = clusters  ? reader.cut(*clusters)
                    : maxCost ? reader.cutByCost(*maxCost)
                              : reader.cutByDepth(*depth);
            }
            std::vector<int64_t> nodes(cut.size());
            std::vector<uint64_t> ranges(2 * cut.size());
            for (size_t i = 0; i < cut.size(); ++i) {
              nodes[i] = cut[i].node == kNoNode ? -1 : static_cast<int64_t>(cut[i].node);
              ranges[2 * i] = cut[i].first, ranges[2 * i + 1] = cut[i].count;
            }
            const auto n = static_cast<py::ssize_t>(cut.size());
            return py::make_tuple(arrayOwning(std::move(nodes), {n}), arrayOwning(std::move(ranges), {n, 2}));
          },
          py::kw_only(), py::arg("clusters") = py::none(), py::arg("max_cost") = py::none(),
          py::arg("depth") = py::none(),
          R"(A cut of the hierarchy in face order, by one of: clusters (the shortest prefix of the file whose
cut has at least that many), max_cost (below every node whose effective cost exceeds it) or depth
(below the nodes of that depth and less; the root's is 1). Returns (node_ids, face_ranges): (K,) int64,
-1 for a single face or a subtree that truncation cut off, and (K, 2) uint64 first face and count.)")
      .def(
          "mesh",
          [](PyReader& r, uint64_t node) {
            ClusterFileReader& reader = r.open();
            if (node >= reader.size())
              throw ArgumentError("node " + std::to_string(node) + " past the nodes");
            FaceRangeMesh mesh;
            {
              py::gil_scoped_release release;
              const FchNode record = reader.node(node);
              mesh = reader.faces(record.first, record.count);
            }
            return meshTuple(std::move(mesh));
          },
          py::arg("node"),
          R"(The triangles of a node: (vertices, triangles, original_ids), (V, 3) float32, (F, 3) uint32 into
vertices (numbered locally, in the file's vertex order) and (F,) uint64 face ids of the input mesh.)")
      .def(
          "faces",
          [](PyReader& r, uint64_t first, uint64_t count) {
            ClusterFileReader& reader = r.open();
            const uint64_t triangles = reader.header().triangleCount;
            if (first > triangles || count > triangles - first)
              throw ArgumentError("faces [" + std::to_string(first) + ", +" + std::to_string(count) +
                                  ") past the " + std::to_string(triangles) + " triangles");
            FaceRangeMesh mesh;
            {
              py::gil_scoped_release release;
              mesh = reader.faces(first, count);
            }
            return meshTuple(std::move(mesh));
          },
          py::arg("first"), py::arg("count"),
          "The triangles of face positions [first, first + count), as mesh() gives a node's.")
      .def(
          "intersect",
          [](PyReader& r, const py::object& origins, const py::object& directions, const py::object& tMax,
             float tMin, unsigned threads) {
            const RayArrays arrays(origins, directions, tMax, tMin);
            const auto n = static_cast<py::ssize_t>(arrays.n);
            py::array_t<float> t(n), uv({n, py::ssize_t{2}});
            py::array_t<int64_t> face(n), original(n);
            float *tp = t.mutable_data(), *uvp = uv.mutable_data();
            int64_t *fp = face.mutable_data(), *op = original.mutable_data();
            castRays(
                r, arrays, [&](auto& index, auto& rays) { return intersect(index, rays, {threads}); },
                [&](size_t first, const std::vector<RayHit>& hits) {
                  for (size_t k = 0; k < hits.size(); ++k) {
                    const size_t i = first + k;
                    const bool hit = hits[k].face != kNoHit;
                    tp[i] = hits[k].t;
                    fp[i] = hit ? static_cast<int64_t>(hits[k].face) : -1;
                    op[i] = hit ? static_cast<int64_t>(hits[k].originalFace) : -1;
                    uvp[2 * i] = hits[k].u, uvp[2 * i + 1] = hits[k].v;
                  }
                });
            return py::make_tuple(t, face, original, uv);
          },
          py::arg("origins"), py::arg("directions"), py::arg("t_max") = py::none(), py::arg("t_min") = 0.0f,
          py::arg("threads") = 0,
          R"(The closest hit of each ray through the hierarchy under the reader's cap. The first query reads
the file whole when it and its layout for rays fit half the cap (then queries run at the speed of
the file in memory), else lays the nodes out by subtree in pages of a temporary file; the reader
keeps either for the next queries, until close(). Returns (t, face, original_id, uv), (N,) float32 t (inf for a miss), (N,) int64 positions
in the file's face order and original face ids (-1 for a miss), (N, 2) float32 barycentrics of the
hit triangle's corners 1 and 2. origins, directions: (N, 3); t_max: a number or (N,) array. The
results do not depend on threads (0: all cores, at most 8); the GIL is released.)")
      .def(
          "occluded",
          [](PyReader& r, const py::object& origins, const py::object& directions, const py::object& tMax,
             float tMin, unsigned threads) {
            const RayArrays arrays(origins, directions, tMax, tMin);
            py::array_t<bool> out(static_cast<py::ssize_t>(arrays.n));
            bool* p = out.mutable_data();
            castRays(
                r, arrays, [&](auto& index, auto& rays) { return occluded(index, rays, {threads}); },
                [&](size_t first, const std::vector<uint8_t>& any) {
                  for (size_t k = 0; k < any.size(); ++k) p[first + k] = any[k] != 0;
                });
            return out;
          },
          py::arg("origins"), py::arg("directions"), py::arg("t_max") = py::none(), py::arg("t_min") = 0.0f,
          py::arg("threads") = 0,
          "Whether each ray meets a triangle for t in [t_min, t_max]: (N,) bool; as intersect().")
      .def(
          "overlap",
          [](PyReader& r, const py::object& low, const py::object& high, unsigned threads) {
            const Floats lo = Floats::ensure(low), hi = Floats::ensure(high);
            if (!lo || lo.ndim() != 2 || lo.shape(1) != 3 || !hi || hi.ndim() != 2 || hi.shape(1) != 3 ||
                hi.shape(0) != lo.shape(0))
              throw ArgumentError("overlap: lo and hi must be (N, 3) arrays of as many boxes");
            std::vector<QueryBox> boxes(static_cast<size_t>(lo.shape(0)));
            for (size_t i = 0; i < boxes.size(); ++i) {
              const glm::vec3 a(lo.data()[3 * i], lo.data()[3 * i + 1], lo.data()[3 * i + 2]);
              const glm::vec3 b(hi.data()[3 * i], hi.data()[3 * i + 1], hi.data()[3 * i + 2]);
              boxes[i].center = 0.5f * (a + b), boxes[i].halfExtent = 0.5f * (b - a);
            }
            return overlapTuple(r, boxes, threads);
          },
          py::arg("lo"), py::arg("hi"), py::arg("threads") = 0,
          R"(The triangles overlapping each axis-aligned box [lo[i], hi[i]] (touching counts), through the
hierarchy under the reader's cap: (offsets, faces), box i's face positions (increasing) being
faces[offsets[i]:offsets[i + 1]]. The GIL is released.)")
      .def(
          "overlap_oriented",
          [](PyReader& r, const py::object& centers, const py::object& halfExtents, const py::object& axes,
             unsigned threads) {
            return overlapTuple(r, orientedBoxes(centers, halfExtents, axes), threads);
          },
          py::arg("centers"), py::arg("half_extents"), py::arg("axes"), py::arg("threads") = 0,
          R"(The triangles overlapping each oriented box: centre centers[i], half extents half_extents[i]
along the box's axes, the columns of the rotation axes[i] ((N, 3, 3); a box's point is
centers[i] + axes[i] @ s with |s| <= half_extents[i]). Touching counts; the result is as overlap()'s.)")
      .def(
          "nearest",
          [](PyReader& r, const py::object& points, std::optional<float> radius, unsigned threads) {
            using Floats = py::array_t<float, py::array::c_style | py::array::forcecast>;
            const Floats p = Floats::ensure(points);
            if (!p || p.ndim() != 2 || p.shape(1) != 3)
              throw ArgumentError("nearest: points must be an (N, 3) array");
            std::vector<glm::vec3> at(static_cast<size_t>(p.shape(0)));
            for (size_t i = 0; i < at.size(); ++i)
              at[i] = {p.data()[3 * i], p.data()[3 * i + 1], p.data()[3 * i + 2]};
            r.open();
            std::vector<NearestHit> hits;
            {
              py::gil_scoped_release release;
              hits = nearest(r.queries(), at, radius.value_or(std::numeric_limits<float>::infinity()),
                             {threads});
            }
            const auto n = static_cast<py::ssize_t>(hits.size());
            std::vector<float> distance(hits.size()), point(3 * hits.size());
            std::vector<int64_t> face(hits.size()), original(hits.size());
            for (size_t i = 0; i < hits.size(); ++i) {
              const bool hit = hits[i].face != kNoHit;
              distance[i] = hits[i].distance;
              face[i] = hit ? static_cast<int64_t>(hits[i].face) : -1;
              original[i] = hit ? static_cast<int64_t>(hits[i].originalFace) : -1;
              for (int a = 0; a < 3; ++a) point[3 * i + a] = hits[i].point[a];
            }
            return py::make_tuple(arrayOwning(std::move(distance), {n}), arrayOwning(std::move(face), {n}),
                                  arrayOwning(std::move(original), {n}),
                                  arrayOwning(std::move(point), {n, 3}));
          },
          py::arg("points"), py::arg("radius") = py::none(), py::arg("threads") = 0,
          R"(The nearest surface point to each of (N, 3) points, within radius (None: any distance), through
the hierarchy under the reader's cap: (distance, face, original_id, point), (N,) float32 (inf when no
triangle is within the radius), (N,) int64 positions in the file's face order and original ids (-1
then), (N, 3) float32 points. The GIL is released.)");

  // A reader of `name`, opened by `from` (a path or a descriptor) with the GIL released.
  const auto open = [](const std::string& name, uint64_t memory, const std::filesystem::path& tmp,
                       const auto& from) {
    PyReader r;
    r.path = name;
    ReaderOptions options;
    options.memoryBytes = memory;
    options.tmp = tmp;
    py::gil_scoped_release release;
    r.reader = from(options);
    return r;
  };
  m.def(
      "_open",
      [open](const std::filesystem::path& path, uint64_t memory, const std::filesystem::path& tmp) {
        return open(path.string(), memory, tmp,
                    [&](const ReaderOptions& o) { return std::make_unique<ClusterFileReader>(path, o); });
      },
      py::arg("path"), py::arg("memory") = 0, py::arg("tmp") = std::filesystem::path());
  m.def(
      "_open_fd",
      [open](int fd, const std::string& name, uint64_t memory, const std::filesystem::path& tmp) {
        return open(name, memory, tmp,
                    [&](const ReaderOptions& o) { return std::make_unique<ClusterFileReader>(fd, name, o); });
      },
      py::arg("fd"), py::arg("name"), py::arg("memory") = 0, py::arg("tmp") = std::filesystem::path());
}

}  // namespace facetree::python
