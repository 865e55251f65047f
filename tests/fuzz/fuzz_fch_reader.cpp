// fuzz_fch_reader: the lazy cluster-file reader (ClusterFileReader) driven by random access over
// corrupted files: nodes in an order the input picks, passes with a frontier budget small enough to
// go to its temporary file, cuts by count, cost and depth, face ranges, the pieces of a cut and the
// queries through a query index (rays, boxes, nearest points). As
// in fuzz_fch, every input is read as given and with its checksums recomputed. Error (Input) is the
// documented error; anything else crashes. Where the whole-file reader reads the file, verify under
// the cap must give its verdict; where it also verifies, the lazy reader must give the same nodes,
// cuts and cut fits.
#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "facetree/io.h"
#include "facetree/query.h"
#include "fuzz_fch_file.h"

using namespace facetree;

namespace {

using namespace facetree::fuzz;

// A small generator seeded by the input, for the order of the random accesses.
struct Picks {
  uint64_t state;
  uint64_t next(uint64_t bound) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return bound ? (state >> 33) % bound : 0;
  }
};

bool sameNode(const FchNode& a, const FchNode& b) {
  return a.first == b.first && a.count == b.count && a.childCount == b.childCount && a.flags == b.flags &&
         std::equal(a.child, a.child + a.childCount, b.child) &&
         std::bit_cast<uint32_t>(a.cost) == std::bit_cast<uint32_t>(b.cost) &&
         std::bit_cast<uint32_t>(a.area) == std::bit_cast<uint32_t>(b.area);
}

// clusterCut's per-face numbering against the reader's clusters.
bool sameRuns(const std::vector<uint32_t>& label, const std::vector<CutCluster>& cut) {
  size_t c = 0;
  for (uint64_t p = 0; p < label.size(); ++p) {
    if (p > 0 && label[p] != label[p - 1]) ++c;
    if (c >= cut.size() || p < cut[c].first || p >= cut[c].first + cut[c].count) return false;
  }
  return c + 1 == cut.size() || (label.empty() && cut.empty());
}

// Rays through the header's bounding box, boxes and points about it, chosen by the input.
struct Queries {
  std::vector<Ray> rays;
  std::vector<QueryBox> boxes;
  std::vector<glm::vec3> points;
};

Queries queriesFor(const FileHeader& header, Picks& picks) {
  Queries q;
  const auto unit = [&] { return float(picks.next(1000)) / 1000.0f; };
  const glm::vec3 lo = header.boundsMin, extent = header.boundsMax - header.boundsMin;
  const auto point = [&](float grow) {
    return lo - grow * extent + (1.0f + 2.0f * grow) * glm::vec3(unit(), unit(), unit()) * extent;
  };
  for (int i = 0; i < 8; ++i) {
    Ray r;
    r.origin = point(1.0f);
    r.direction = point(0.0f) - r.origin;
    q.rays.push_back(r);
    q.boxes.push_back({point(0.1f), 0.1f * extent * unit(), glm::quat(1, 0, 0, 0)});
    q.points.push_back(point(0.5f));
  }
  return q;
}

void exercise(const std::string& path, Picks picks) {
  ReaderOptions options;
  options.memoryBytes = 64 << 10;  // 16 KiB of frontier: larger files spill
  std::vector<FchNode> nodes;
  std::vector<CutCluster> cut16, depth3;
  std::vector<RayHit> hits;
  Queries queries;
  try {
    ClusterFileReader reader(path, options);
    const uint64_t n = reader.size(), triangles = reader.header().triangleCount;
    reader.forEachNode([&](uint64_t, const FchNode& node, uint32_t depth) {
      if (depth == 0) fail("a node of depth 0");
      nodes.push_back(node);
      return nodes.size() < 200000;
    });
    for (int i = 0; i < 16 && n > 0; ++i) (void)reader.node(picks.next(n));
    cut16 = reader.cut(16);
    depth3 = reader.cutByDepth(3);
    if (!nodes.empty()) (void)reader.cutByCost(nodes[picks.next(nodes.size())].cost);
    uint64_t covered = 0;
    for (const CutCluster& c : cut16) {
      if (c.first != covered) fail("cut: clusters not in face order");
      covered += c.count;
    }
    if (covered != triangles) fail("cut: the clusters do not cover the faces");
    for (int i = 0; i < 4 && triangles > 0; ++i) {
      const uint64_t first = picks.next(triangles),
                     count = 1 + picks.next(std::min<uint64_t>(triangles - first, 500));
      const FaceRangeMesh mesh = reader.faces(first, count);
      if (mesh.indices.size() != 3 * count || mesh.originalFace.size() != count) fail("faces: wrong counts");
      for (const uint32_t v : mesh.indices)
        if (v >= mesh.vertices.size()) fail("faces: a local index past the vertices");
    }
    uint64_t pieces = 0;
    reader.forEachCutPiece(cut16, [&](const FaceRangeMesh& piece, std::span<const uint32_t> clusterOf) {
      if (clusterOf.size() != piece.originalFace.size()) fail("pieces: a cluster per triangle");
      pieces += clusterOf.size();
    });
    if (pieces != triangles) fail("pieces: the pieces do not cover the faces");
    ReaderQueryIndex index(reader);
    queries = queriesFor(reader.header(), picks);
    hits = intersect(index, queries.rays, {2});
    (void)occluded(index, queries.rays, {1});
    (void)overlap(index, queries.boxes, {2});
    (void)nearest(index, queries.points, std::numeric_limits<float>::infinity(), {1});
  } catch (const Error& e) {
    checkMessage(e.what());
    return;
  }
  // Read and verified whole: the lazy reader's nodes and cuts are the whole file's.
  ClusterFile file;
  try {
    file = readClusterFile(path);
  } catch (const Error&) {
    return;  // a frame the lazy reader had no need of
  }
  // verify under the cap gives the verdict of the file in memory, broken or not.
  const VerifyResult whole = verifyClusterFile(file);
  {
    ClusterFileReader reader(path, options);
    const VerifyResult streamed = verifyClusterFile(reader);
    if (streamed.ok != whole.ok || streamed.message != whole.message)
      fail("verify under the cap: '" + streamed.message + "' against '" + whole.message + "'");
  }
  if (!whole.ok) return;
  // The cuts' fits under the cap (the Morton order sorted in runs of the temporary file) to the bit.
  {
    const uint64_t counts[] = {1, 16, 300};
    ClusterFileReader reader(path, options);
    const std::vector<CutFit> a = cutFits(file, counts), b = cutFits(reader, counts);
    const auto bits = [](double v) { return std::bit_cast<uint64_t>(v); };
    for (size_t i = 0; i < a.size(); ++i)
      if (a[i].clusters != b[i].clusters || bits(a[i].sumFit) != bits(b[i].sumFit) ||
          bits(a[i].sumAreaFit) != bits(b[i].sumAreaFit) || bits(a[i].sumBoxArea) != bits(b[i].sumBoxArea) ||
          bits(a[i].mortonBoxArea) != bits(b[i].mortonBoxArea) || a[i].smallClusters != b[i].smallClusters)
        fail("cutFits under the cap differ from the whole file's at cut " + std::to_string(counts[i]));
  }
  for (size_t j = 0; j < nodes.size(); ++j)
    if (!sameNode(nodes[j], file.nodes[j]))
      fail("node " + std::to_string(j) + " differs from the whole file's");
  if (!sameRuns(clusterCut(file, 16), cut16)) fail("cut(16) differs from clusterCut");
  // The closest hits through the reader's index are the file in memory's.
  const std::vector<RayHit> inMemory = intersect(file, queries.rays, {1});
  for (size_t i = 0; i < hits.size(); ++i)
    if (hits[i].face != inMemory[i].face ||
        std::bit_cast<uint32_t>(hits[i].t) != std::bit_cast<uint32_t>(inMemory[i].t))
      fail("ray " + std::to_string(i) + ": the reader's hit differs from the file in memory's");
  if (!sameRuns(clusterDepthCut(file, 3), depth3)) fail("cutByDepth(3) differs from clusterDepthCut");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static MemFile file;
  const Picks picks{fch::xxh64(data, size)};
  exercise(file.write(data, size), picks);
  std::vector<uint8_t> fixed(data, data + size);
  fixChecksums(fixed);
  if (fixed.size() >= fch::kHeaderBytes && std::memcmp(fixed.data(), data, size) != 0)
    exercise(file.write(fixed.data(), fixed.size()), picks);
  return 0;
}
