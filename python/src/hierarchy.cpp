// facetree.Hierarchy: a cluster file in memory (built, or loaded from a .fch) with its nodes as
// NumPy arrays. Fields stored per node are read-only views into the nodes (no copy; they keep the
// hierarchy alive); derived ones (children, parent, effective cost, box axes) are computed.
#include <algorithm>
#include <cstddef>

#include <glm/gtc/quaternion.hpp>

#include "bindings.h"

namespace facetree::python {
namespace {

constexpr py::ssize_t kNodeStride = sizeof(FchNode);

// A read-only view of `count` records of T at `first`, `stride` bytes apart, kept alive by `owner`.
template <typename T>
py::array nodeField(const py::object& owner, const T* first, size_t count, std::vector<py::ssize_t> shape,
                    std::vector<py::ssize_t> strides) {
  if (count == 0) return py::array_t<T>(shape);
  py::array view(py::dtype::of<T>(), shape, strides, first, owner);
  view.attr("setflags")(py::arg("write") = false);
  return view;
}

PyHierarchy& self(const py::object& object) {
  return object.cast<PyHierarchy&>();
}

// Whether a child reference is a node the file holds (not a face, not cut off by truncation).
bool isNodeChild(const ClusterFile& file, uint32_t ref) {
  return !(ref & kFaceChild) && !file.isCutOff(ref);
}

// A property viewing one field of every node: `width` values of T per node (0: one).
template <typename T, typename Field>
auto nodeColumn(Field field, py::ssize_t width = 0) {
  return [field, width](const py::object& o) {
    const std::vector<FchNode>& n = self(o).file.nodes;
    const T* first = n.empty() ? nullptr : field(n[0]);
    const auto count = static_cast<py::ssize_t>(n.size());
    if (width == 0) return nodeField(o, first, n.size(), {count}, {kNodeStride});
    return nodeField(o, first, n.size(), {count, width}, {kNodeStride, sizeof(T)});
  };
}

// Per input face: its cluster in `cut` (given per face in hierarchy order), -1 for input faces the
// hierarchy does not hold (triangles dropped for non-finite vertices).
py::array_t<int64_t> byInputFace(const PyHierarchy& h, const std::vector<uint32_t>& cut) {
  std::vector<int64_t> labels(h.inputFaces, -1);
  for (size_t i = 0; i < cut.size(); ++i) labels[h.file.originalFace[i]] = cut[i];
  return arrayOwning(std::move(labels), {static_cast<py::ssize_t>(h.inputFaces)});
}

}  // namespace

py::dict headerDict(const FileHeader& f) {
  py::dict d;
  d["version"] = f.version;
  d["node_count"] = f.nodeCount;
  d["original_node_count"] = f.originalNodeCount;
  d["triangle_count"] = f.triangleCount;
  d["vertex_count"] = f.vertexCount;
  d["branching"] = f.branching;
  d["metric"] = metricName(f.metric);
  d["k"] = f.k;
  d["flat_threshold"] = f.flatThreshold;
  d["memory_cap_bytes"] = f.memoryCapBytes;
  d["boxes"] = boxesName(f.boxes);
  d["top"] = f.topClusters;
  d["bounds_min"] = py::make_tuple(f.boundsMin.x, f.boundsMin.y, f.boundsMin.z);
  d["bounds_max"] = py::make_tuple(f.boundsMax.x, f.boundsMax.y, f.boundsMax.z);
  return d;
}

void registerHierarchy(py::module_& m) {
  py::class_<PyHierarchy> c(m, "Hierarchy", R"(A face cluster hierarchy and its reordered mesh.

Nodes are in file order: by decreasing effective cost, the root first, every parent before its
children, so any prefix (truncate) is a valid, coarser hierarchy. Node i holds the faces
face_order[first:first + count] of its face range; its children partition that range.)");
  c.def("__len__", [](const PyHierarchy& h) { return h.file.nodes.size(); })
      .def("__repr__",
           [](const PyHierarchy& h) {
             return "<facetree.Hierarchy: " + std::to_string(h.file.nodes.size()) + " nodes, " +
                    std::to_string(h.file.indices.size() / 3) + " faces, branching " +
                    std::to_string(h.file.header.branching) + ">";
           })
      .def_property_readonly(
          "node_count", [](const PyHierarchy& h) { return h.file.nodes.size(); }, "Number of nodes.")
      .def_property_readonly(
          "face_count", [](const PyHierarchy& h) { return h.file.indices.size() / 3; },
          "Number of triangles the hierarchy holds.")
      .def_property_readonly(
          "input_face_count", [](const PyHierarchy& h) { return h.inputFaces; },
          "Number of faces of the input: the length of the labels cut() returns.")
      .def_property_readonly(
          "branching", [](const PyHierarchy& h) { return h.file.header.branching; },
          "Largest number of children of a node (2, 4 or 8).")
      .def_property_readonly(
          "height", [](const PyHierarchy& h) { return branchingStats(h.file).height; },
          "Nodes on the longest path from the root to a face, the face included.")
      .def_property_readonly(
          "truncated",
          [](const PyHierarchy& h) { return h.file.header.nodeCount < h.file.header.originalNodeCount; },
          "Whether nodes were cut off (a truncated file or truncate()).")
      .def_property_readonly(
          "report", [](const PyHierarchy& h) { return h.report; },
          "The build's report (the fields of `facetree build --json`), None for a loaded file.")
      .def_property_readonly(
          "header", [](const PyHierarchy& h) { return headerDict(h.file.header); },
          "The file header: counts and the options the hierarchy was built with.")
      .def_property_readonly(
          "face_ranges", nodeColumn<uint32_t>([](const FchNode& n) { return &n.first; }, 2),
          "(N, 2) uint32: each node's first face (a position in face_order) and face count.")
      .def_property_readonly("child_count",
                             nodeColumn<uint8_t>([](const FchNode& n) { return &n.childCount; }),
                             "(N,) uint8: children of each node, single faces included.")
      .def_property_readonly(
          "children",
          [](const PyHierarchy& h) {
            const uint32_t b = h.file.header.branching;
            std::vector<int64_t> out(h.file.nodes.size() * b, -1);
            for (size_t i = 0; i < h.file.nodes.size(); ++i) {
              const FchNode& node = h.file.nodes[i];
              for (uint32_t k = 0; k < node.childCount && k < b; ++k)
                if (isNodeChild(h.file, node.child[k])) out[i * b + k] = node.child[k];
            }
            return arrayOwning(std::move(out), {static_cast<py::ssize_t>(h.file.nodes.size()), b});
          },
          "(N, branching) int64: child node indices in face-range order; -1 where the child is a single "
          "face, was cut off by truncation, or the slot is empty.")
      .def_property_readonly(
          "parent",
          [](const PyHierarchy& h) {
            std::vector<int64_t> out(h.file.nodes.size(), -1);
            for (size_t i = 0; i < h.file.nodes.size(); ++i) {
              const FchNode& node = h.file.nodes[i];
              for (uint32_t k = 0; k < node.childCount; ++k)
                if (isNodeChild(h.file, node.child[k])) out[node.child[k]] = int64_t(i);
            }
            return arrayOwning(std::move(out), {static_cast<py::ssize_t>(h.file.nodes.size())});
          },
          "(N,) int64: each node's parent, -1 for the root.")
      .def_property_readonly(
          "face_order",
          [](const py::object& o) {
            const auto& f = self(o).file.originalFace;
            return nodeField(o, f.data(), f.size(), {static_cast<py::ssize_t>(f.size())}, {sizeof(uint64_t)});
          },
          "(F,) uint64: the input face of each position of the hierarchy's face order.")
      .def_property_readonly(
          "cost", nodeColumn<float>([](const FchNode& n) { return &n.cost; }),
          "(N,) float32: each node's merge cost when it was created (Willmott 2000, eq. 84).")
      .def_property_readonly(
          "effective_cost",
          [](const PyHierarchy& h) {
            const auto& n = h.file.nodes;
            std::vector<float> out(n.size());
            // Children follow their parents: one pass from the last node up.
            for (size_t i = n.size(); i-- > 0;) {
              out[i] = n[i].cost;
              for (uint32_t k = 0; k < n[i].childCount; ++k)
                if (isNodeChild(h.file, n[i].child[k])) out[i] = std::max(out[i], out[n[i].child[k]]);
            }
            return arrayOwning(std::move(out), {static_cast<py::ssize_t>(n.size())});
          },
          "(N,) float32: the largest merge cost in each node's subtree. Nodes are in decreasing order of it "
          "for branching 2; a wider tree keeps the order of the binary tree it groups.")
      .def_property_readonly("area", nodeColumn<float>([](const FchNode& n) { return &n.area; }),
                             "(N,) float32: surface area of each node's faces.")
      .def_property_readonly("perimeter", nodeColumn<float>([](const FchNode& n) { return &n.perimeter; }),
                             "(N,) float32: boundary length of each node's cluster.")
      .def_property_readonly("sum_normal",
                             nodeColumn<float>([](const FchNode& n) { return &n.sumNormal.x; }, 3),
                             "(N, 3) float32: S, the sum of area-weighted face normals; |S| is projArea.")
      .def_property_readonly(
          "flags", nodeColumn<uint8_t>([](const FchNode& n) { return &n.flags; }),
          "(N,) uint8: bit 0 joins disjoint surfaces, bit 1 flat frame, bit 2 some child cut off.")
      .def_property_readonly("box_center",
                             nodeColumn<float>([](const FchNode& n) { return &n.box.center.x; }, 3),
                             "(N, 3) float32: centre of each node's oriented box.")
      .def_property_readonly(
          "box_axes",
          [](const PyHierarchy& h) {
            std::vector<float> out(h.file.nodes.size() * 9);
            for (size_t i = 0; i < h.file.nodes.size(); ++i) {
              const glm::mat3 axes = glm::mat3_cast(h.file.nodes[i].box.orientation);
              for (int a = 0; a < 3; ++a)
                for (int j = 0; j < 3; ++j) out[9 * i + 3 * a + j] = axes[a][j];
            }
            return arrayOwning(std::move(out), {static_cast<py::ssize_t>(h.file.nodes.size()), 3, 3});
          },
          "(N, 3, 3) float32: the box axes, one unit vector per row.")
      .def_property_readonly(
          "box_half_extents", nodeColumn<float>([](const FchNode& n) { return &n.box.halfExtent.x; }, 3),
          "(N, 3) float32: half the box's size along each axis; every vertex of the node lies inside, "
          "and each side touches one.")
      .def_property_readonly(
          "box_side_areas", nodeColumn<float>([](const FchNode& n) { return &n.box.sideArea[0]; }, 6),
          "(N, 6) float32: projected area of the node's faces facing +axis0, -axis0, +axis1, -axis1, "
          "+axis2, -axis2.")
      .def_property_readonly(
          "vertices",
          [](const py::object& o) {
            const auto& v = self(o).file.vertices;
            return nodeField(o, v.empty() ? nullptr : &v[0].x, v.size(),
                             {static_cast<py::ssize_t>(v.size()), 3}, {sizeof(glm::vec3), sizeof(float)});
          },
          "(V, 3) float32: the reordered mesh's vertices, numbered by first use.")
      .def_property_readonly(
          "triangles",
          [](const py::object& o) {
            const auto& t = self(o).file.indices;
            return nodeField(o, t.data(), t.size(), {static_cast<py::ssize_t>(t.size() / 3), 3},
                             {3 * sizeof(uint32_t), sizeof(uint32_t)});
          },
          "(F, 3) uint32: the reordered mesh's triangles, in hierarchy order (row i is face_order[i]).")
      .def(
          "cut",
          [](const PyHierarchy& h, uint64_t clusters) {
            if (clusters == 0) throw ArgumentError("cut: clusters must be at least 1");
            return byInputFace(h, clusterCut(h.file, clusters));
          },
          py::arg("clusters"),
          "A cut of at least `clusters` clusters (all faces when there are fewer): the shortest prefix of "
          "nodes giving that many. Returns (input_face_count,) int64, the cluster of each input face, "
          "clusters numbered 0, 1, ... along the face order; -1 for faces the hierarchy does not hold.")
      .def(
          "depth_cut",
          [](const PyHierarchy& h, uint32_t depth) { return byInputFace(h, clusterDepthCut(h.file, depth)); },
          py::arg("depth"),
          "A cut keeping the nodes above `depth` (0: the root is the one cluster); as cut().")
      .def(
          "cut_fit",
          [](const PyHierarchy& h, uint64_t clusters) {
            const CutFit fit = cutFit(h.file, clusters);
            return py::dict(py::arg("clusters") = fit.clusters, py::arg("sum_fit") = fit.sumFit,
                            py::arg("sum_area_fit") = fit.sumAreaFit, py::arg("sum_box_area") = fit.sumBoxArea,
                            py::arg("morton_box_area") = fit.mortonBoxArea,
                            py::arg("small_clusters") = fit.smallClusters);
          },
          py::arg("clusters"),
          "How well the cut of `clusters` clusters fits the surface: the sums of eFit and area * eFit "
          "(Willmott 2000, eq. 84) over its clusters; lower is better. And how spatially coherent it is: "
          "the sum of its boxes' surface areas, and that of as many runs of the faces in Morton order. "
          "And how balanced: small_clusters counts its clusters under 1% of the average cluster's area.")
      .def(
          "truncate",
          [](const PyHierarchy& h, uint64_t nodes) {
            if (nodes == 0) throw ArgumentError("truncate: keep at least 1 node");
            PyHierarchy out;
            out.file = h.file;
            out.inputFaces = h.inputFaces;
            truncateInMemory(out.file, nodes);
            return out;
          },
          py::arg("nodes"), "The hierarchy of the first `nodes` nodes (a coarser one; the mesh is kept).")
      .def(
          "verify",
          [](const PyHierarchy& h) {
            const VerifyResult result = verifyClusterFile(h.file);
            if (!result.ok) throw ArgumentError(result.message);
          },
          "Checks every invariant of the format (face ranges, parents, box containment and tightness, "
          "areas); "
          "raises InputError naming the first violation.")
      .def(
          "save",
          [](const PyHierarchy& h, const std::filesystem::path& path, int zstdLevel) {
            if (zstdLevel < 1 || zstdLevel > 19) throw ArgumentError("save: zstd_level must be 1 to 19");
            py::gil_scoped_release release;
            writeClusterFile(path, h.file, WriteOptions{.zstdLevel = zstdLevel});
          },
          py::arg("path"), py::arg("zstd_level") = 3,
          "Writes the cluster file (.fch), atomically: the bytes `facetree build` writes for the same mesh "
          "and options.");
  m.def(
      "cluster_colours",
      [](py::array_t<int64_t, py::array::c_style | py::array::forcecast> labels) {
        std::vector<uint8_t> out(size_t(labels.size()) * 3, 0);
        const int64_t* l = labels.data();
        for (py::ssize_t i = 0; i < labels.size(); ++i) {
          if (l[i] < 0) continue;
          const glm::u8vec3 c = clusterColour(static_cast<uint32_t>(l[i]));
          out[3 * i] = c.r, out[3 * i + 1] = c.g, out[3 * i + 2] = c.b;
        }
        return arrayOwning(std::move(out), {labels.size(), 3});
      },
      py::arg("labels"),
      "(n, 3) uint8 colours of cluster ids, as `facetree render` and `facetree export` colour them; "
      "black for -1.");
}

}  // namespace facetree::python
