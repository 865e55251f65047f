// facetree/picture: pictures of a clustering, to look at a cut by eye: flat-shaded PNGs of a
// mesh's clusters or of a cluster file's cut (rasterized), PNGs by ray casting through the
// hierarchy, and PLYs coloured by cluster. Public header of the module: std, glm and the headers
// of merge, io and query.
//
// Errors: as io's writers (facetree::Error of category Output naming the file);
// std::invalid_argument for inconsistent arguments.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>

#include <glm/glm.hpp>

#include "facetree/io.h"
#include "facetree/merge.h"
#include "facetree/query.h"

namespace facetree {

// Pictures and coloured exports of a clustering. `faceCluster[i]` is the cluster of triangle i
// of `mesh`; colours are a deterministic function of the cluster id.
struct RenderOptions {
  int width = 1024, height = 768;  // of the picture, in pixels
  // Viewing direction (from the camera towards the model) and up vector; the camera frames the
  // bounding box. Zero means the default three-quarter view.
  glm::vec3 viewDirection{0.0f};
  glm::vec3 up{0.0f, 0.0f, 1.0f};
};
// Orthonormal camera frame: `forward` points from the camera towards the model, `up` is the
// screen's up direction, `right` = forward x up.
struct ViewBasis {
  glm::vec3 right;
  glm::vec3 up;
  glm::vec3 forward;
};
// Zero or non-finite `viewDirection` means the default three-quarter view looking down.
// `up` falls back to +z, and then to +y, when it is zero or (nearly) parallel to the view.
ViewBasis makeViewBasis(glm::vec3 viewDirection, glm::vec3 up);
// Writes `rgb` (3 bytes a pixel, rows from the top) as a PNG at `path`, atomically.
void writePng(const std::filesystem::path& path, std::span<const uint8_t> rgb, int width, int height);

// Deterministic colour of a cluster id, as the pictures and exports below colour it. Hue advances
// by the golden angle (137.5 degrees) from one id to the next, so consecutive ids always differ
// strongly; saturation and value come from a mixed hash of the id, so ids whose hues happen to be
// close still differ in lightness.
glm::u8vec3 clusterColour(uint32_t cluster);

// Flat-shaded software rendering to PNG (written atomically).
void renderClustersPng(const MeshView& mesh, std::span<const uint32_t> faceCluster,
                       const RenderOptions& options, const std::filesystem::path& path);
// Binary PLY with a per-face uchar red/green/blue colour by cluster (viewable in MeshLab).
void writeClusterColouredPly(const MeshView& mesh, std::span<const uint32_t> faceCluster,
                             const std::filesystem::path& path);
// The same pictures and meshes of a cut (ClusterFileReader's, in face order; cluster ids are
// positions in it) read a frame at a time: the same bytes as the whole-file calls. `clusterIds`
// adds a uint `cluster` property to every face.
void renderClustersPng(ClusterFileReader& reader, std::span<const CutCluster> cut,
                       const RenderOptions& options, const std::filesystem::path& path);
void writeClusterColouredPly(ClusterFileReader& reader, std::span<const CutCluster> cut,
                             const std::filesystem::path& path, bool clusterIds = false);

// A picture by ray casting, to check the queries by eye: one ray per pixel, orthographic, along
// options.viewDirection, framing the file's bounding box; a hit is grey by the angle between its
// triangle and the view, a miss white. Through the reader, under its cap.
void renderRaycastPng(ClusterFileReader& reader, const RenderOptions& options,
                      const std::filesystem::path& path, const QueryOptions& queryOptions = {},
                      QueryStats* stats = nullptr);

}  // namespace facetree
