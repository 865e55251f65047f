// facetree/io: writes and reads what the merge produced: the cluster file, mesh writers,
// exports and pictures. Public header of the module.
//
// Errors: throws facetree::Error of category Output (facetree/error.h) naming the file and the reason.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>

#include <glm/ext/vector_uint3_sized.hpp>
#include <glm/vec3.hpp>

#include "facetree/error.h"
#include "io/branching.h"
#include "io/cluster_file.h"
#include "merge/merge.h"

namespace facetree {

// Every output of this module (cluster files, meshes, pictures) is written under this
// temporary name beside `path` (unique per process) and renamed to `path` when complete; a
// writer that fails or is destroyed first removes it. Exposed for a caller that must clean up
// without unwinding, e.g. a command-line tool exiting on a signal.
std::filesystem::path temporaryOutputPath(const std::filesystem::path& path);

// Whether an output is written in place as a stream instead: "-" (standard output), or a
// target that exists and is neither a regular file nor a directory (a named pipe, a device).
// Streams take bytes in order, have no temporary name, and cannot be removed on failure.
bool isStreamOutput(const std::filesystem::path& path);
// Throws Error (Output) ("PATH: cannot create: REASON") when `path` is a directory or its directory is
// missing or not writable: checked before long work, so that it does not fail at its end.
// Stream outputs pass.
void checkOutputWritable(const std::filesystem::path& path);

// Streaming binary little-endian PLY writer (float x,y,z; uchar-count int indices). Counts
// are given up front so nothing is held in memory. Writes to a temporary name beside the
// target and renames on finish(); a writer destroyed before finish() removes its file.
class PlyWriter {
 public:
  PlyWriter(const std::filesystem::path& path, uint64_t vertexCount, uint64_t triangleCount);
  ~PlyWriter();
  PlyWriter(const PlyWriter&) = delete;
  PlyWriter& operator=(const PlyWriter&) = delete;
  void addVertex(const glm::vec3& position);
  void addTriangle(uint32_t a, uint32_t b, uint32_t c);
  void finish();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// Synthetic meshes for tests and benchmarks, streamed to binary PLY (nothing is held in
// memory but the input of a subdivision), optionally with vertices and/or faces shuffled by
// a keyed bijection so any size can be shuffled while streaming.
enum class SyntheticKind { Grid, Sphere, Terrain, Strip };
struct GenerateOptions {
  uint64_t triangles = 20000;  // approximate target; the shape rounds it
  bool shuffleVertices = false;
  bool shuffleFaces = false;
  uint64_t seed = 1;
};
struct GeneratedCounts {
  uint64_t vertices = 0;
  uint64_t triangles = 0;
};
// Grid: flat regular square grid in z = 0 (Willmott 2000, Fig. 70). Sphere: UV sphere of
// radius 1. Terrain: grid with multi-octave value-noise heights. Strip: one row of square
// cells (with Metric::Constant its hierarchy is a chain as deep as the strip is long).
GeneratedCounts writeSyntheticMesh(SyntheticKind kind, const GenerateOptions& options,
                                   const std::filesystem::path& path);
// Midpoint subdivision, `levels` times at once: every triangle becomes 4^levels triangles;
// points on shared edges are shared so the result stays connected.
GeneratedCounts writeSubdividedMesh(const MeshView& mesh, unsigned levels, const GenerateOptions& options,
                                    const std::filesystem::path& path);

// Pictures and coloured exports of a clustering. `faceCluster[i]` is the cluster of triangle i
// of `mesh`; colours are a deterministic function of the cluster id.
struct RenderOptions {
  int width = 1024;
  int height = 768;
  // Viewing direction (from the camera towards the model) and up vector; the camera frames the
  // bounding box. Zero means the default three-quarter view.
  glm::vec3 viewDirection{0.0f};
  glm::vec3 up{0.0f, 0.0f, 1.0f};
};
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

}  // namespace facetree
