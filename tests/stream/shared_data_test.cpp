// The shared real meshes (FACETREE_SHARED_DATA/*.ply.zst): counts match the README table.
#include <gtest/gtest.h>

#include <map>

#include "facetree/stream.h"

namespace facetree {
namespace {

struct Counts {
  uint64_t vertices;
  uint64_t faces;
};

// From shared/data/README.md.
const std::map<std::string, Counts>& readmeCounts() {
  static const std::map<std::string, Counts> counts = {
      {"fg_hawaii", {1056077, 3192083}},
      {"matterport_cedar_creek", {564270, 1091591}},
      {"dragon_vrip", {437645, 871414}},
      {"openfoam_buildings", {200062, 400020}},
      {"turbine_blade_200k", {99519, 199034}},
      {"cura_ultimaker_robot", {94009, 187974}},
      {"openfoam_dtc_hull", {58033, 116062}},
      {"nefertiti_100k", {49971, 99938}},
      {"horse_97k", {48485, 96966}},
      {"bunny_zipper", {35947, 69451}},
      {"grey_nurse_shark", {25057, 49702}},
      {"tigerfighter_31k", {15713, 31421}},
      {"pepper_scan", {14980, 29956}},
      {"rocker_arm", {10044, 20088}},
      {"gears_cad", {9723, 19426}},
      {"fandisk", {6475, 12946}},
      {"openfoam_flange", {3228, 6468}},
      {"bunny_npm_lowres", {1839, 3674}},
  };
  return counts;
}

constexpr size_t kBatch = 1 << 16;

TEST(StreamSharedData, EveryMeshHasTheCountsOfTheReadme) {
  const std::filesystem::path folder = FACETREE_SHARED_DATA;
  if (!std::filesystem::is_directory(folder)) GTEST_SKIP() << "no shared data at " << folder;
  std::vector<Triangle> batch(kBatch);
  int meshes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    const std::string file = entry.path().filename().string();
    constexpr std::string_view kSuffix = ".ply.zst";
    if (file.size() <= kSuffix.size() || !file.ends_with(kSuffix)) continue;
    const std::string name = file.substr(0, file.size() - kSuffix.size());
    SCOPED_TRACE(name);
    const auto known = readmeCounts().find(name);
    ASSERT_NE(known, readmeCounts().end()) << "mesh missing from the table";
    auto reader = openMesh(entry.path());
    EXPECT_TRUE(reader->info().zstdCompressed);
    EXPECT_EQ(reader->info().format, MeshFormat::PlyBinaryLittleEndian);
    EXPECT_EQ(reader->info().declaredVertices, known->second.vertices);
    EXPECT_EQ(reader->info().declaredFaces, known->second.faces);
    uint64_t triangles = 0;
    uint64_t lastFace = 0;
    bool ordered = true;
    while (const size_t count = reader->read(batch)) {
      for (size_t i = 0; i < count; ++i) {
        ordered = ordered && batch[i].face >= lastFace;
        lastFace = batch[i].face;
      }
      triangles += count;
    }
    const ReadStats& stats = reader->stats();
    EXPECT_EQ(stats.vertices, known->second.vertices);
    EXPECT_EQ(stats.faces, known->second.faces);
    EXPECT_EQ(stats.triangles, triangles);
    EXPECT_GE(stats.triangles, stats.faces);  // all faces are triangles or larger polygons
    EXPECT_EQ(stats.nonFiniteVertices, 0u);
    EXPECT_TRUE(ordered);
    ++meshes;
  }
  EXPECT_EQ(meshes, static_cast<int>(readmeCounts().size()));
}

// The README's zero-area column counts faces whose area is exactly zero; ours counts
// triangles with a repeated index or exactly collinear corners (all meshes are triangles).
TEST(StreamSharedData, DegenerateCountsOfDragonMatchTheReadme) {
  const std::filesystem::path path = std::filesystem::path(FACETREE_SHARED_DATA) / "dragon_vrip.ply.zst";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "no " << path;
  auto reader = openMesh(path);
  std::vector<Triangle> batch(kBatch);
  while (reader->read(batch) != 0) {
  }
  EXPECT_EQ(reader->stats().degenerateTriangles, 108u);
  EXPECT_EQ(reader->stats().triangles, 871414u);
}

}  // namespace
}  // namespace facetree
