// facetree/generate: synthetic meshes for tests and benchmarks (`facetree gen`), and the
// subdivision that makes any mesh larger. Public header of the module: std, glm and the headers
// of merge and io.
//
// Errors: as io's writers (facetree::Error of category Output naming the file);
// std::invalid_argument for inconsistent arguments.
#pragma once

#include <cstdint>
#include <filesystem>

#include "facetree/io.h"
#include "facetree/merge.h"

namespace facetree {

// Synthetic meshes for tests and benchmarks, streamed to binary PLY (nothing is held in
// memory but the input of a subdivision), optionally with vertices and/or faces shuffled by
// a keyed bijection so any size can be shuffled while streaming.
enum class SyntheticKind { Grid, Sphere, Terrain, Strip, Assembly, TiledScan };
// Size, shuffling and seed of a synthetic mesh.
struct GenerateOptions {
  uint64_t triangles = 20000;  // approximate target; the shape rounds it
  // Shuffled orders, as scans written in no spatial order have them (seeded: reproducible).
  bool shuffleVertices = false, shuffleFaces = false;
  uint64_t seed = 1;
};
// What a generator wrote.
struct GeneratedCounts {
  uint64_t vertices = 0;   // vertices written
  uint64_t triangles = 0;  // triangles written
};
// Grid: flat regular square grid in z = 0 (Willmott 2000, Fig. 70). Sphere: UV sphere of
// radius 1. Terrain: grid with multi-octave value-noise heights. Strip: one row of square
// cells (with Metric::Constant its hierarchy is a chain as deep as the strip is long). Assembly: two
// groups of closed unit boxes 30 units apart, 9 in each, most touching with the shared faces stored
// by both boxes (their own vertices), as CAD parts exported one by one are. TiledScan: the terrain
// in 9 x 9 tiles that share no vertex, each in 6 to 11 pieces (two material groups, the second
// around a hole, one to six islands in the hole), as scans delivered per tile are.
GeneratedCounts writeSyntheticMesh(SyntheticKind kind, const GenerateOptions& options,
                                   const std::filesystem::path& path);
// Midpoint subdivision, `levels` times at once: every triangle becomes 4^levels triangles;
// points on shared edges are shared so the result stays connected.
GeneratedCounts writeSubdividedMesh(const MeshView& mesh, unsigned levels, const GenerateOptions& options,
                                    const std::filesystem::path& path);

}  // namespace facetree
