// Tiles (facetree/tiles.h): the tiles partition the faces, a tile's content keeps its border at full
// resolution at every level (no cracks between any two levels), geometric errors grow strictly
// towards the root, the glb holds the positions it was given, and the writer's bytes are the same
// for every thread count; bad options and outputs fail cleanly and leave nothing behind.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "facetree/tiles.h"
#include "merge/test_meshes.h"
#include "tiles/glb.h"
#include "tiles/tile_borders.h"
#include "tiles/tile_content.h"
#include "tiles/tile_tree.h"

namespace facetree {
namespace {

using namespace tiles;

// A folder removed with everything in it at the end of the test.
struct ScratchDirectory {
  std::filesystem::path path = std::filesystem::temp_directory_path() /
                               ("facetree_tiles_" + std::to_string(::getpid()) + "_" +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
  ScratchDirectory() {
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~ScratchDirectory() { std::filesystem::remove_all(path); }
};

std::filesystem::path writeFile(const test::TestMesh& mesh, const std::filesystem::path& path,
                                uint64_t keep = 0) {
  const MeshView view{mesh.positions, mesh.indices};
  ClusterFile file = makeClusterFile(view, {}, buildHierarchy(view, BuildOptions{}), FileOptions{});
  if (keep) truncateInMemory(file, keep);
  writeClusterFile(path, file);
  return path;
}

// Edges used by one triangle alone, by the file's vertex ids.
std::set<std::pair<uint64_t, uint64_t>> openEdges(const std::vector<const TileMesh*>& meshes) {
  std::map<std::pair<uint64_t, uint64_t>, int> uses;
  for (const TileMesh* m : meshes)
    for (size_t t = 0; t < m->indices.size(); t += 3)
      for (int e = 0; e < 3; ++e) {
        const uint64_t a = m->vertexIds[m->indices[t + e]], b = m->vertexIds[m->indices[t + (e + 1) % 3]];
        ++uses[{std::min(a, b), std::max(a, b)}];
      }
  std::set<std::pair<uint64_t, uint64_t>> open;
  for (const auto& [edge, count] : uses)
    if (count == 1) open.insert(edge);
  return open;
}

std::map<std::string, std::string> filesUnder(const std::filesystem::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir))
    if (entry.is_regular_file()) {
      std::ifstream in(entry.path(), std::ios::binary);
      std::ostringstream bytes;
      bytes << in.rdbuf();
      files[std::filesystem::relative(entry.path(), dir).string()] = bytes.str();
    }
  return files;
}

TEST(TileTree, TilesPartitionTheFacesAndLeavesHoldAtMostATile) {
  ScratchDirectory scratch;
  for (const uint64_t keep : {uint64_t{0}, uint64_t{40}}) {
    const test::TestMesh mesh = test::grid(120);  // 28,800 faces
    const auto fch = writeFile(mesh, scratch.path / "grid.fch", keep);
    ClusterFileReader reader(fch);
    const TileTree tree = chooseTiles(reader, 1024);
    ASSERT_GT(tree.tiles.size(), 20u);
    EXPECT_EQ(tree.tiles[0].first, 0u);
    EXPECT_EQ(tree.tiles[0].count, mesh.indices.size() / 3);
    uint64_t leafFaces = 0, next = 0, bottomTiles = 0, bottomChildren = 0, twoLeafTiles = 0;
    for (const uint32_t t : tree.postorder()) {
      const Tile& tile = tree.tiles[t];
      if (!tile.childCount) {
        EXPECT_LE(tile.count, 1024u) << "keep " << keep;
        EXPECT_EQ(tile.first, next) << "leaves in face order, without gaps";
        next = tile.first + tile.count;
        leafFaces += tile.count;
        continue;
      }
      EXPECT_GT(tile.count, 1024u);
      EXPECT_NE(tile.node, kNoNode);
      uint64_t first = tile.first;
      for (uint32_t k = 0; k < tile.childCount; ++k) {
        const Tile& child = tree.tiles[tree.children[tile.firstChild + k]];
        EXPECT_EQ(child.first, first) << "children partition their parent's range";
        EXPECT_EQ(child.depth, tile.depth + 1);
        first += child.count;
      }
      EXPECT_EQ(first, tile.first + tile.count);
      if (keep == 0) {
        EXPECT_LE(tile.childCount, kTileChildren);
        bool aboveLeaves = true;
        for (uint32_t k = 0; k < tile.childCount; ++k)
          aboveLeaves = aboveLeaves && !tree.tiles[tree.children[tile.firstChild + k]].childCount;
        if (aboveLeaves)
          ++bottomTiles, bottomChildren += tile.childCount, twoLeafTiles += tile.childCount == 2;
      }
    }
    EXPECT_EQ(leafFaces, mesh.indices.size() / 3);
    if (keep == 0) {
      // The level above the leaves opens its nodes as far as the others do.
      EXPECT_GE(bottomChildren, 4 * bottomTiles) << bottomTiles << " tiles above the leaves";
      EXPECT_LE(4 * twoLeafTiles, bottomTiles) << "two-leaf tiles";
    }
  }
}

std::set<std::pair<uint64_t, uint64_t>> edgesOf(const std::vector<const TileMesh*>& meshes) {
  std::set<std::pair<uint64_t, uint64_t>> edges;
  for (const TileMesh* m : meshes)
    for (size_t t = 0; t < m->indices.size(); t += 3)
      for (int e = 0; e < 3; ++e) {
        const uint64_t a = m->vertexIds[m->indices[t + e]], b = m->vertexIds[m->indices[t + (e + 1) % 3]];
        edges.insert({std::min(a, b), std::max(a, b)});
      }
  return edges;
}

// Made bottom-up as the writer makes them: every edge an inner tile's leaves share with a leaf
// outside it is an open edge of its content, at full resolution, so a tile meets its neighbours at
// whatever level either is shown; the mesh's own boundary (the grid's rim) is not held: the root
// keeps fewer of its edges than the leaves have.
TEST(TileContent, EveryLevelKeepsTheEdgesItSharesAndErrorsGrowStrictly) {
  ScratchDirectory scratch;
  for (const test::TestMesh& mesh : {test::grid(100), test::icosphere(5)}) {
    const auto fch = writeFile(mesh, scratch.path / "mesh.fch");
    ClusterFileReader reader(fch);
    const TileTree tree = chooseTiles(reader, 512);
    const TileBorders borders(reader, tree);
    std::vector<TileMesh> content(tree.tiles.size());
    std::vector<const TileMesh*> leafContents;
    uint64_t innerFaces = 0, leafFaces = 0, checkedEdges = 0;
    for (const uint32_t t : tree.postorder()) {
      const Tile& tile = tree.tiles[t];
      if (!tile.childCount) {
        content[t] = leafContent(reader, tile.first, tile.count);
        EXPECT_EQ(content[t].indices.size(), 3 * tile.count);
        EXPECT_EQ(content[t].error, 0.0);
        EXPECT_EQ(tile.firstLeaf, leafContents.size());
        leafContents.push_back(&content[t]);
        leafFaces += tile.count;
        continue;
      }
      std::vector<const TileMesh*> children;
      size_t childFaces = 0;
      for (uint32_t k = 0; k < tile.childCount; ++k) {
        children.push_back(&content[tree.children[tile.firstChild + k]]);
        childFaces += children.back()->indices.size() / 3;
      }
      content[t] = innerContent(children, 512, [&](const glm::vec3& p) {
        return borders.lockedIn(p, tile.firstLeaf, tile.leafCount);
      });
      for (const TileMesh* child : children) EXPECT_GT(content[t].error, child->error);
      EXPECT_LT(content[t].indices.size() / 3, childFaces) << "an inner tile simplifies";
      innerFaces += content[t].indices.size() / 3;
    }
    for (const uint32_t t : tree.postorder()) {
      const Tile& tile = tree.tiles[t];
      if (!tile.childCount) continue;
      const std::vector<const TileMesh*> inside(leafContents.begin() + tile.firstLeaf,
                                                leafContents.begin() + tile.firstLeaf + tile.leafCount);
      std::vector<const TileMesh*> outside(leafContents.begin(), leafContents.begin() + tile.firstLeaf);
      outside.insert(outside.end(), leafContents.begin() + tile.firstLeaf + tile.leafCount,
                     leafContents.end());
      const auto outsideEdges = edgesOf(outside), open = openEdges({&content[t]});
      for (const auto& edge : openEdges(inside))
        if (outsideEdges.count(edge)) {
          EXPECT_TRUE(open.count(edge))
              << "tile " << t << " lost the shared edge " << edge.first << "-" << edge.second;
          ++checkedEdges;
        }
    }
    EXPECT_GT(checkedEdges, 100u);
    EXPECT_GT(content[0].error, 0.0);
    EXPECT_LT(innerFaces, leafFaces * 6 / 10) << "the levels above the leaves, against the leaves";
    const size_t rim = openEdges(leafContents).size();
    EXPECT_LT(openEdges({&content[0]}).size(), rim == 0 ? 1 : rim) << "the mesh's own boundary simplifies";
  }
}

// Two pieces that meet without sharing vertices (one's border has twice the other's points, as
// terrain tiles meet): the points of that crack are locked at every level, even in the root, so
// that neither side's border moves off the other's.
TEST(TileBorders, ACracksPointsAreLockedAtEveryLevel) {
  ScratchDirectory scratch;
  test::TestMesh mesh;
  const int n = 40;
  auto add = [&](float x0, int columns, float dx, int rows, float dy) {
    const uint32_t base = static_cast<uint32_t>(mesh.positions.size());
    for (int j = 0; j <= rows; ++j)
      for (int i = 0; i <= columns; ++i)
        mesh.positions.emplace_back(x0 + i * dx, j * dy, 0.002f * (x0 + i * dx) * (j * dy));
    for (int j = 0; j < rows; ++j)
      for (int i = 0; i < columns; ++i) {
        const uint32_t a = base + j * (columns + 1) + i, b = a + 1, c = a + columns + 2, d = a + columns + 1;
        mesh.indices.insert(mesh.indices.end(), {a, b, c, a, c, d});
      }
  };
  add(-float(n), n, 1.0f, n, 1.0f);  // x in [-n, 0], a point every 1 along x = 0
  add(0.0f, n, 1.0f, 2 * n, 0.5f);   // x in [0, n], a point every 0.5 along x = 0
  const auto fch = writeFile(mesh, scratch.path / "cracked.fch");
  ClusterFileReader reader(fch);
  const TileTree tree = chooseTiles(reader, 512);
  const TileBorders borders(reader, tree);
  const Tile& root = tree.tiles[0];
  ASSERT_GT(root.leafCount, 4u);
  int seam = 0;
  for (const glm::vec3& p : mesh.positions)
    if (p.x == 0.0f && p.y > 0.0f && p.y < float(n)) {
      EXPECT_TRUE(borders.lockedIn(p, root.firstLeaf, root.leafCount)) << p.y;
      ++seam;
    }
  EXPECT_EQ(seam, (n - 1) + (2 * n - 1));  // both pieces' points inside the seam
  // A point of the mesh's own boundary, far from the crack, is not locked in the root.
  EXPECT_FALSE(borders.lockedIn(glm::vec3(-float(n), 20.0f, 0.0f), root.firstLeaf, root.leafCount));
}

// Coincident vertices of different parts (touching boxes each storing the faces they share) do not
// hold the simplifier back: two grids on top of each other simplify as far as one.
TEST(TileContent, CoincidentPartsSimplifyByTheirOwnTopology) {
  const test::TestMesh grid = test::grid(60);
  TileMesh a, b;
  for (TileMesh* m : {&a, &b}) {
    m->positions = grid.positions;
    m->indices = grid.indices;
    const uint64_t base = m == &a ? 0 : grid.positions.size();
    for (size_t v = 0; v < grid.positions.size(); ++v) m->vertexIds.push_back(base + v);
  }
  const std::vector<const TileMesh*> one{&a}, two{&a, &b};
  const auto none = [](const glm::vec3&) { return false; };
  const TileMesh single = innerContent(one, 1000, none), pair = innerContent(two, 2000, none);
  EXPECT_LE(single.indices.size() / 3, 1000u);
  EXPECT_LE(pair.indices.size() / 3, 2000u);
}

// A surface tessellated finer than it bends simplifies past a quarter, down to an eighth, at no
// error that shows; one whose quarter already strays keeps its quarter; below a quarter the
// error stays under 1/4096 of the extent.
TEST(TileContent, FineTessellationSimplifiesPastAQuarterWithinTheFinestDetail) {
  const auto none = [](const glm::vec3&) { return false; };
  struct Case {
    test::TestMesh mesh;
    bool fine;
  };
  for (const Case& c : {Case{test::grid(60), true}, Case{test::icosphere(2), false}}) {
    TileMesh child;
    child.positions = c.mesh.positions;
    child.indices = c.mesh.indices;
    for (size_t v = 0; v < child.positions.size(); ++v) child.vertexIds.push_back(v);
    const std::vector<const TileMesh*> children{&child};
    const TileMesh out = innerContent(children, 1u << 20, none);
    const size_t faces = c.mesh.indices.size() / 3, kept = out.indices.size() / 3;
    glm::vec3 lo = c.mesh.positions[0], hi = lo;
    for (const glm::vec3& p : c.mesh.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    EXPECT_LE(kept, faces / 4);
    if (c.fine)
      EXPECT_LE(kept, faces / 8) << "a flat grid loses nothing by simplifying";
    else
      EXPECT_GT(kept, faces / 8) << "a coarse sphere's quarter strays already";
    if (kept < faces / 4)
      EXPECT_LE(out.error, extent / 4096);
    else
      EXPECT_GT(out.error, extent / 4096);
  }
}

TEST(Glb, HoldsThePositionsRelativeToTheCentreYUpAndPadsItsChunks) {
  TileMesh mesh;
  mesh.positions = {{1, 2, 3}, {4, 5, 6}, {7, 8, 10}};
  mesh.vertexIds = {0, 1, 2};
  mesh.indices = {0, 1, 2};
  const glm::dvec3 centre(4, 5, 6);
  const std::string glb = glbBytes(mesh, centre, {});
  uint32_t header[5];
  std::memcpy(header, glb.data(), sizeof header);
  EXPECT_EQ(header[0], 0x46546C67u);
  EXPECT_EQ(header[1], 2u);
  EXPECT_EQ(header[2], glb.size());
  EXPECT_EQ(header[3] % 4, 0u);
  const std::string json = glb.substr(20, header[3]);
  EXPECT_NE(json.find("\"translation\":[4,6,-5]"), std::string::npos) << json;
  uint32_t bin[2];
  std::memcpy(bin, glb.data() + 20 + header[3], sizeof bin);
  EXPECT_EQ(bin[1], 0x004E4942u);
  EXPECT_EQ(bin[0] % 4, 0u);
  float local[9];
  std::memcpy(local, glb.data() + 28 + header[3], sizeof local);
  // (x, y, z) - centre, then glTF's y up: (x, z, -y).
  const float expected[9] = {-3, -3, 3, 0, 0, 0, 3, 4, -3};
  for (int i = 0; i < 9; ++i) EXPECT_EQ(local[i], expected[i]) << i;
}

TEST(WriteTileset, SameBytesForEveryThreadCountAndExternalTilesets) {
  ScratchDirectory scratch;
  const auto fch = writeFile(test::icosphere(6), scratch.path / "sphere.fch");  // 81,920 faces
  TileOptions options;
  options.tileFaces = 2048;
  options.threads = 1;
  const TilesetReport one = writeTileset(fch, scratch.path / "one", options);
  options.threads = 3;
  const TilesetReport three = writeTileset(fch, scratch.path / "three", options);
  EXPECT_EQ(one.leafTriangles, 81920u);
  EXPECT_GT(one.leafTiles, 40u);
  EXPECT_GE(one.levels, 3u);
  EXPECT_EQ(one.tiles, three.tiles);
  uint64_t bytes = 0;
  for (const auto& [name, content] : filesUnder(scratch.path / "one")) bytes += content.size();
  EXPECT_EQ(one.bytes, bytes);
  EXPECT_EQ(filesUnder(scratch.path / "one"), filesUnder(scratch.path / "three"));
  EXPECT_LE(one.bytes, one.leafBytes * 16 / 10);
  options.tilesPerJson = 8;
  const TilesetReport split = writeTileset(fch, scratch.path / "split", options);
  EXPECT_GT(split.jsonFiles, 3u);
  for (const auto& [name, bytes] : filesUnder(scratch.path / "split"))
    if (name.ends_with(".json")) {
      size_t tiles = 0;
      for (size_t at = 0; (at = bytes.find("\"boundingVolume\"", at)) != std::string::npos; ++at) ++tiles;
      EXPECT_LE(tiles, 8u + 8u) << name << ": its tiles and the links to the files below it";
    }
  // Written again over itself: replaced.
  EXPECT_EQ(writeTileset(fch, scratch.path / "one", options).tiles, split.tiles);
}

TEST(WriteTileset, BadOptionsAndOutputsFailWithoutLeavingAnything) {
  ScratchDirectory scratch;
  const auto fch = writeFile(test::icosphere(4), scratch.path / "sphere.fch");
  TileOptions options;
  options.tileFaces = 8;
  EXPECT_THROW(writeTileset(fch, scratch.path / "out", options), std::invalid_argument);
  options.tileFaces = 256;
  std::ofstream(scratch.path / "plain") << "not a folder";
  try {
    writeTileset(fch, scratch.path / "plain", options);
    ADD_FAILURE() << "a file in the way";
  } catch (const Error& e) {
    EXPECT_EQ(e.category(), ErrorCategory::Output);
    EXPECT_EQ(std::string(e.what()), (scratch.path / "plain").string() + ": exists and is not a directory");
  }
  std::filesystem::create_directories(scratch.path / "other");
  std::ofstream(scratch.path / "other" / "notes.txt") << "someone's";
  try {
    writeTileset(fch, scratch.path / "other", options);
    ADD_FAILURE() << "a folder that is not a tileset";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              (scratch.path / "other").string() + ": exists and is not a tileset; not replaced");
  }
  EXPECT_TRUE(std::filesystem::exists(scratch.path / "other" / "notes.txt"));
  try {
    writeTileset(scratch.path / "missing.fch", scratch.path / "out", options);
    ADD_FAILURE() << "a missing file";
  } catch (const Error& e) {
    EXPECT_EQ(e.category(), ErrorCategory::Input);
    EXPECT_NE(std::string(e.what()).find("missing.fch"), std::string::npos) << e.what();
  }
  int polls = 0;
  options.cancelled = [&polls] { return ++polls > 3; };
  try {
    writeTileset(fch, scratch.path / "out", options);
    ADD_FAILURE() << "not cancelled";
  } catch (const Error& e) {
    EXPECT_EQ(e.category(), ErrorCategory::Cancelled);
  }
  std::set<std::string> left;
  for (const auto& entry : std::filesystem::directory_iterator(scratch.path))
    left.insert(entry.path().filename());
  EXPECT_EQ(left, (std::set<std::string>{"other", "plain", "sphere.fch"}));
}

}  // namespace
}  // namespace facetree

namespace facetree {
namespace {

TEST(TilesAsTasks, TheBytesOfOneProcessAResumedPlanAndAChangedTaskNamed) {
  ScratchDirectory scratch;
  const auto fch = writeFile(test::icosphere(5), scratch.path / "sphere.fch");  // 20,480 faces
  TileOptions options;
  options.tileFaces = 1024;
  options.threads = 2;
  writeTileset(fch, scratch.path / "one", options);
  const std::filesystem::path work = scratch.path / "work";
  const TilesPlanReport plan = planTiles(fch, scratch.path / "tasks", work, options, 6);
  ASSERT_GE(plan.tasks, 6u);
  EXPECT_TRUE(plan.planned);
  EXPECT_EQ(plan.tileFaces, 1024u);
  for (uint32_t task = plan.tasks; task-- > 0;) EXPECT_TRUE(runTilesTask(work, task));
  EXPECT_FALSE(runTilesTask(work, 0)) << "done already";
  EXPECT_THROW(runTilesTask(work, plan.tasks), std::invalid_argument);
  // The same plan again keeps its tasks; a task's manifest changed since it was written is named.
  EXPECT_FALSE(planTiles(fch, scratch.path / "tasks", work, options, 6).planned);
  const std::filesystem::path task2 = work / "tiles-2.manifest";
  std::string bytes = filesUnder(work).at("tiles-2.manifest");
  bytes[bytes.size() / 2] ^= 1;
  std::ofstream(task2, std::ios::binary | std::ios::trunc) << bytes;
  try {
    finishTiles(work);
    ADD_FAILURE() << "a changed task manifest";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), task2.string() + ": checksum mismatch (changed since it was written)");
  }
  std::filesystem::remove(task2);
  EXPECT_TRUE(runTilesTask(work, 2));
  const TilesetReport r = finishTiles(work);
  EXPECT_EQ(r.dir, std::filesystem::absolute(scratch.path / "tasks"));
  EXPECT_EQ(filesUnder(scratch.path / "one"), filesUnder(scratch.path / "tasks"));
  EXPECT_FALSE(std::filesystem::exists(work / "tileset"));
  // Other options plan afresh: the earlier plan's tasks go.
  options.tileFaces = 2048;
  EXPECT_TRUE(planTiles(fch, scratch.path / "tasks", work, options, 6).planned);
  EXPECT_FALSE(std::filesystem::exists(work / "tiles-0.manifest"));
}

TEST(Glb, DracoLeavesOutTrianglesOnOneVertexAndATileOfOnlyThoseGoesUncompressed) {
  TileMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  mesh.vertexIds = {0, 1, 2, 3};
  mesh.indices = {0, 1, 2, 1, 1, 3, 1, 3, 2};
  GlbOptions options;
  options.draco = true;
  options.gridMin = glm::dvec3(-1);
  options.gridSize = 4;
  const std::string glb = glbBytes(mesh, glm::dvec3(0), options);
  EXPECT_NE(glb.find("KHR_draco_mesh_compression"), std::string::npos);
  EXPECT_NE(glb.find("\"count\":6,\"type\":\"SCALAR\""), std::string::npos) << "two triangles of three";
  mesh.indices = {0, 0, 1, 2, 3, 3};
  const std::string plain = glbBytes(mesh, glm::dvec3(0), options);
  EXPECT_EQ(plain.find("KHR_draco_mesh_compression"), std::string::npos);
  EXPECT_NE(plain.find("\"count\":6,\"type\":\"SCALAR\""), std::string::npos);
}

}  // namespace
}  // namespace facetree
