// ClusterFileWriter: a .fch written piece by piece. Same bytes as the whole-file writer however the
// pieces come, memory of a few frames for millions of nodes, standard output, clean failures
// (unfinished, disk full, hook veto, bad counts), and files whose vertices are stored twice.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <random>

#include "../cli/run_cli.h"
#include "../sanitizers.h"
#include "facetree/io.h"
#include "facetree/merge.h"
#include "facetree/picture.h"
#include "fch_test_util.h"

namespace facetree {
namespace {

using namespace facetree::test;

// A fresh empty directory, removed when the test ends.
struct ScratchDir {
  std::filesystem::path path;
  explicit ScratchDir(const std::string& name) : path(scratch(name + "_dir")) {
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
  size_t entries() const {
    return static_cast<size_t>(std::distance(std::filesystem::directory_iterator(path), {}));
  }
};

// A valid cluster file of `triangles` triangles generated piece by piece, nothing held but a
// stack of log2(triangles) ranges: a balanced binary hierarchy in preorder (children follow their
// parent; a subtree of c faces holds c - 1 nodes, which places the right child), a strip of
// triangles (i, i+1, i+2) and original ids 2i + 1000. Boxes and statistics are arbitrary
// (structure only: verify with boxes and statistics off).
class SyntheticFile {
 public:
  explicit SyntheticFile(uint64_t triangles, bool noisyVertices = false)
      : triangles_(triangles), noisy_(noisyVertices) {
    if (triangles >= 2) stack_.push_back({0, static_cast<uint32_t>(triangles)});
  }
  StreamFileInfo info() const {
    StreamFileInfo info;
    info.header.nodeCount = triangles_ >= 2 ? triangles_ - 1 : 0;
    info.header.triangleCount = triangles_;
    info.header.vertexCount = triangles_ ? triangles_ + 2 : 0;
    info.header.k = 3e-4;
    info.maxOriginalFace = triangles_ ? 2 * (triangles_ - 1) + 1000 : 0;
    return info;
  }
  // The next up to `n` items of each stream (empty when the stream is done).
  std::span<const FchNode> nodes(size_t n) {
    nodeBatch_.clear();
    while (nodeBatch_.size() < n && !stack_.empty()) {
      const Range r = stack_.back();
      stack_.pop_back();
      const uint64_t self = nextNode_++;
      const uint32_t half = r.count / 2, rest = r.count - half;
      FchNode node;
      node.first = r.first;
      node.count = r.count;
      node.childCount = 2;
      node.child[0] = half == 1 ? kFaceChild | r.first : static_cast<uint32_t>(self + 1);
      node.child[1] =
          rest == 1 ? kFaceChild | (r.first + half) : static_cast<uint32_t>(self + 1 + (half - 1));
      node.childFaces[0] = half;
      node.childFaces[1] = rest;
      node.flags = self % 3 == 0 ? kFchFlatFrame : 0;
      node.cost = float(self) * 0.25f;
      node.area = float(r.count);
      node.perimeter = std::sqrt(float(r.count));
      node.sumNormal = {0.0f, 0.0f, float(r.count)};
      node.box.center = {float(r.first), 0.5f, 0.0f};
      node.box.orientation = glm::quat(1, 0, 0, 0);
      node.box.halfExtent = {float(r.count) * 0.5f, 0.5f, 0.1f};
      const float sides[6] = {0.25f, 0.25f, 0.0f, 0.0f, 1.0f, 0.0f};  // S . axis = side+ - side-
      for (int k = 0; k < 6; ++k) node.box.sideArea[k] = sides[k] * node.area;
      nodeBatch_.push_back(node);
      if (rest >= 2) stack_.push_back({r.first + half, rest});
      if (half >= 2) stack_.push_back({r.first, half});
    }
    return nodeBatch_;
  }
  std::span<const glm::vec3> vertices(size_t n) {
    vertexBatch_.clear();
    const uint64_t total = info().header.vertexCount;
    for (; vertexBatch_.size() < n && nextVertex_ < total; ++nextVertex_) {
      const auto i = static_cast<float>(nextVertex_);
      if (noisy_)
        vertexBatch_.push_back({float(rng_()) * 1e-6f, float(rng_()) * 1e-6f, float(rng_()) * 1e-6f});
      else
        vertexBatch_.push_back({0.5f * i, std::sin(i), std::cos(0.3f * i)});
    }
    return vertexBatch_;
  }
  // Triangles: fills `indices` and `ids` with up to n triangles.
  size_t triangles(size_t n, std::vector<uint32_t>& indices, std::vector<uint64_t>& ids) {
    indices.clear(), ids.clear();
    for (; ids.size() < n && nextTriangle_ < triangles_; ++nextTriangle_) {
      const auto t = static_cast<uint32_t>(nextTriangle_);
      indices.insert(indices.end(), {t, t + 1, t + 2});
      ids.push_back(2 * nextTriangle_ + 1000);
    }
    return ids.size();
  }

  // The whole file in memory (small sizes only).
  ClusterFile materialize() {
    ClusterFile file;
    file.header = info().header;
    for (auto s = nodes(1000); !s.empty(); s = nodes(1000))
      file.nodes.insert(file.nodes.end(), s.begin(), s.end());
    for (auto s = vertices(1000); !s.empty(); s = vertices(1000))
      file.vertices.insert(file.vertices.end(), s.begin(), s.end());
    std::vector<uint32_t> indices;
    std::vector<uint64_t> ids;
    while (triangles(1000, indices, ids)) {
      file.indices.insert(file.indices.end(), indices.begin(), indices.end());
      file.originalFace.insert(file.originalFace.end(), ids.begin(), ids.end());
    }
    return file;
  }

 private:
  struct Range {
    uint32_t first, count;
  };
  uint64_t triangles_;
  bool noisy_;
  std::vector<Range> stack_;
  uint64_t nextNode_ = 0, nextVertex_ = 0, nextTriangle_ = 0;
  std::vector<FchNode> nodeBatch_;
  std::vector<glm::vec3> vertexBatch_;
  std::mt19937 rng_{7};
};

// Feeds a whole SyntheticFile to `writer`, streams interleaved in the order `pick` chooses
// (0 nodes, 1 vertices, 2 triangles) with batch sizes from `size` (0: an empty span).
void feed(ClusterFileWriter& writer, SyntheticFile& source, const std::function<int()>& pick,
          const std::function<size_t()>& size) {
  std::vector<uint32_t> indices;
  std::vector<uint64_t> ids;
  bool done[3] = {false, false, false};
  while (!(done[0] && done[1] && done[2])) {
    const int s = pick();
    const size_t n = size();
    if (done[s]) continue;
    if (s == 0) {
      const auto batch = source.nodes(n);
      done[0] = n > 0 && batch.empty();
      writer.addNodes(batch);
    } else if (s == 1) {
      const auto batch = source.vertices(n);
      done[1] = n > 0 && batch.empty();
      writer.addVertices(batch);
    } else {
      done[2] = source.triangles(n, indices, ids) == 0 && n > 0;
      writer.addTriangles(indices, ids);
    }
  }
}

// Runs `body` in a forked child (for rlimits, standard output and peak memory of its own) and
// returns its exit code; what the child writes to `report` comes back in `*reported`.
int inChild(const std::function<int(int report)>& body, std::string* reported = nullptr) {
  int fds[2];
  if (::pipe(fds) != 0) return -1;
  std::fflush(stdout);  // or the child would flush the parent's pending output too
  std::fflush(stderr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    int code = 100;
    try {
      code = body(fds[1]);
    } catch (...) {
      code = 101;
    }
    ::close(fds[1]);
    ::_exit(code);
  }
  ::close(fds[1]);
  std::string text;
  char buffer[4096];
  for (ssize_t got; (got = ::read(fds[0], buffer, sizeof buffer)) > 0;) text.append(buffer, size_t(got));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (reported) *reported = text;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

void say(int fd, const std::string& text) {
  for (size_t done = 0; done < text.size();) {
    const ssize_t got = ::write(fd, text.data() + done, text.size() - done);
    if (got <= 0) return;
    done += size_t(got);
  }
}

WriteOptions smallFrames() {
  WriteOptions options;
  options.nodesPerFrame = 13;
  options.geometryPerFrame = 29;
  return options;
}

// The same options with frames compressed on the writer's helper thread.
WriteOptions threaded(WriteOptions options) {
  options.threads = 2;
  return options;
}

// ---------------------------------------------------------------------------------------------
// Same bytes

TEST(ClusterFileWriter, AnyBatchingAndInterleavingGivesTheWholeFileWritersBytes) {
  Cleanup cleanup;
  const auto whole = cleanup.add(scratch("whole.fch")), streamed = cleanup.add(scratch("streamed.fch"));
  for (const uint64_t triangles : {0, 1, 2, 3, 500, 1000}) {
    for (const WriteOptions& options : {WriteOptions{}, smallFrames()}) {
      SyntheticFile reference(triangles);
      writeClusterFile(whole, reference.materialize(), options);
      const std::string expected = slurp(whole);
      std::mt19937 rng(static_cast<unsigned>(triangles));
      // Geometry first, nodes first, and random interleavings with random batch sizes.
      const std::function<int()> orders[] = {
          [n = 0]() mutable { return n++ < 1000000 ? 2 - std::min(2, n / 400) : 0; },
          [n = 0]() mutable { return std::min(2, n++ / 400); },
          [&rng] { return int(rng() % 3); },
      };
      for (const auto& order : orders) {
        for (const WriteOptions& streaming : {options, threaded(options)}) {
          const std::function<int()> pick = order;  // a fresh copy of the order's state for each run
          SyntheticFile source(triangles);
          ClusterFileWriter writer(streamed, source.info(), streaming);
          feed(writer, source, pick, [&rng] { return size_t(rng() % 40); });
          EXPECT_EQ(writer.finish(), expected.size());
          ASSERT_EQ(slurp(streamed), expected) << triangles << " triangles, threads " << streaming.threads;
        }
      }
    }
  }
  const ClusterFile back = readClusterFile(streamed);
  VerifyOptions structure;
  structure.boxes = structure.statistics = false;
  const VerifyResult result = verifyClusterFile(back, structure);
  EXPECT_TRUE(result.ok) << result.message;
  EXPECT_EQ(back.nodes.size(), 999u);
}

TEST(ClusterFileWriter, FillsMadeOnTheWorkersGiveTheBytesOfSpansInAnyMix) {
  Cleanup cleanup;
  const auto whole = cleanup.add(scratch("whole_fill.fch")), filled = cleanup.add(scratch("filled.fch"));
  for (const uint64_t triangles : {0, 1, 2, 3, 500, 1000}) {
    for (const WriteOptions& options : {WriteOptions{}, smallFrames()}) {
      const ClusterFile file = SyntheticFile(triangles).materialize();
      writeClusterFile(whole, file, options);
      const std::string expected = slurp(whole);
      std::mt19937 rng(static_cast<unsigned>(triangles) + 1);
      for (const unsigned threads : {1u, 2u, 3u}) {
        WriteOptions streaming = options;
        streaming.threads = threads;
        ClusterFileWriter writer(filled, SyntheticFile(triangles).info(), streaming);
        // Each stream in runs of random length (within a frame, across several, to the end), each
        // run a span or a fill, the streams interleaved at random.
        const uint64_t total[3] = {file.nodes.size(), file.vertices.size(), file.originalFace.size()};
        uint64_t at[3] = {0, 0, 0};
        while (at[0] < total[0] || at[1] < total[1] || at[2] < total[2]) {
          const unsigned s = rng() % 3;
          const uint64_t first = at[s], n = std::min<uint64_t>(total[s] - first, rng() % 70);
          const bool fill = rng() % 2 == 0;
          at[s] += n;
          if (s == 0 && fill)
            writer.addNodes(n, [&file](uint64_t f, std::span<FchNode> out) {
              std::copy_n(file.nodes.begin() + ptrdiff_t(f), out.size(), out.begin());
            });
          else if (s == 0)
            writer.addNodes(std::span(file.nodes).subspan(first, n));
          else if (s == 1 && fill)
            writer.addVertices(n, [&file](uint64_t f, std::span<glm::vec3> out) {
              std::copy_n(file.vertices.begin() + ptrdiff_t(f), out.size(), out.begin());
            });
          else if (s == 1)
            writer.addVertices(std::span(file.vertices).subspan(first, n));
          else if (fill)
            writer.addTriangles(
                n,
                [&file](uint64_t f, std::span<uint32_t> out) {
                  std::copy_n(file.indices.begin() + ptrdiff_t(3 * f), out.size(), out.begin());
                },
                [&file](uint64_t f, std::span<uint64_t> out) {
                  std::copy_n(file.originalFace.begin() + ptrdiff_t(f), out.size(), out.begin());
                });
          else
            writer.addTriangles(std::span(file.indices).subspan(3 * first, 3 * n),
                                std::span(file.originalFace).subspan(first, n));
        }
        EXPECT_EQ(writer.finish(), expected.size());
        ASSERT_EQ(slurp(filled), expected) << triangles << " triangles, threads " << threads;
      }
    }
  }
}

TEST(ClusterFileWriter, StreamedHierarchyGivesTheBytesOfMakeClusterFile) {
  Cleanup cleanup;
  const auto whole = cleanup.add(scratch("made.fch")), streamed = cleanup.add(scratch("streamed_h.fch"));
  // A real build on two separate sheets (a join flag at the root) and a median split with ids.
  TestMesh sheets = gridMesh(14, 9);
  sheets.append(gridMesh(6, 5), glm::vec3(0, 0, 5));
  BuildOptions build;
  build.balanceSlack = 0;
  const Hierarchy built = buildHierarchy(sheets.view(), build);
  const TestMesh grid = gridMesh(20, 13);
  const Hierarchy split = medianSplitHierarchy(grid.view());
  std::vector<uint64_t> ids(grid.indices.size() / 3);
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = (uint64_t{1} << 33) + 3 * i;  // 8-byte ids
  struct Case {
    const TestMesh& mesh;
    const Hierarchy& hierarchy;
    std::span<const uint64_t> ids;
  };
  for (const Case& c : {Case{sheets, built, {}}, Case{grid, split, ids}})
    for (const unsigned b : {2u, 4u, 8u})
      for (const RecastRule rule : {RecastRule::LargestArea, RecastRule::FewestNodes})
        for (const WriteOptions& options : {WriteOptions{}, smallFrames()}) {
          FileOptions fileOptions;
          fileOptions.branching = b;
          fileOptions.rule = rule;
          fileOptions.build.k = 5e-4;
          fileOptions.memoryCapBytes = 77;
          writeClusterFile(whole, makeClusterFile(c.mesh.view(), c.ids, c.hierarchy, fileOptions), options);
          for (const WriteOptions& streaming : {options, threaded(options)}) {
            const uint64_t bytes =
                writeClusterFile(streamed, c.mesh.view(), c.ids, c.hierarchy, fileOptions, streaming);
            EXPECT_EQ(bytes, std::filesystem::file_size(streamed));
            ASSERT_EQ(slurp(streamed), slurp(whole)) << "b = " << b << ", threads " << streaming.threads;
          }
        }
  EXPECT_TRUE(verifyClusterFile(readClusterFile(streamed)).ok);
}

// ---------------------------------------------------------------------------------------------
// Memory

TEST(ClusterFileWriter, MillionsOfNodesInFrameSizedMemory) {
  if (!test::kPeakRssShowsTheCap)
    GTEST_SKIP() << "resident memory under AddressSanitizer (shadow, quarantine) says nothing of the bound";
  // 3M triangles, 3M - 1 nodes (the format allows at most one node fewer than triangles), fed in
  // batches of 1000 from a generator. Held in memory they would take ~540 MB (FchNode is
  // sizeof(FchNode) bytes); the writer may grow the child's peak resident set by
  // writerMemoryBound() (~8 MB at level 1) plus 8 MiB for the allocator and the library.
  constexpr uint64_t kTriangles = 3'000'000;
  WriteOptions options;
  options.zstdLevel = 1;  // memory is the point here, not ratio
  const uint64_t inMemory = (kTriangles - 1) * sizeof(FchNode) + (kTriangles + 2) * sizeof(glm::vec3) +
                            kTriangles * (3 * sizeof(uint32_t) + sizeof(uint64_t));
  const uint64_t bound = writerMemoryBound(options) + (uint64_t{8} << 20);
  ASSERT_LT(bound * 16, inMemory) << "the bound must be far below the data";
  ScratchDir dir("millions");
  const auto path = dir.path / "big.fch";
  std::string report;
  const int code = inChild(
      [&](int out) {
        rusage before{}, after{};
        ::getrusage(RUSAGE_SELF, &before);
        SyntheticFile source(kTriangles);
        ClusterFileWriter writer(path, source.info(), options);
        uint64_t peakSpill = 0;
        feed(
            writer, source, [n = 0]() mutable { return n++ % 3; }, [] { return size_t{1000}; });
        const uint64_t bytes = writer.finish();
        peakSpill = writer.temporaryBytesPeak();
        ::getrusage(RUSAGE_SELF, &after);
        // ru_maxrss in KiB; a forked child starts from the parent's resident set at the fork.
        say(out, std::to_string((after.ru_maxrss - before.ru_maxrss) * 1024) + " " + std::to_string(bytes) +
                     " " + std::to_string(peakSpill));
        return 0;
      },
      &report);
  ASSERT_EQ(code, 0) << report;
  uint64_t growth = 0, bytes = 0, peakSpill = 0;
  std::sscanf(report.c_str(), "%lu %lu %lu", &growth, &bytes, &peakSpill);
  std::printf(
      "peak resident growth %.1f MiB (bound %.1f MiB, data in memory %.0f MiB), file %.1f MB, spill peak "
      "%.1f MB\n",
      growth / 1048576.0, bound / 1048576.0, inMemory / 1048576.0, bytes / 1e6, peakSpill / 1e6);
  EXPECT_LT(growth, bound);
  const FchLayout layout = readClusterFileLayout(path);
  EXPECT_EQ(layout.fileBytes, bytes);
  EXPECT_EQ(layout.header.nodeCount, kTriangles - 1);
  EXPECT_EQ(layout.header.triangleCount, kTriangles);
  EXPECT_EQ(layout.header.vertexCount, kTriangles + 2);
  // Everything but the nodes went through the spill files, all at once before finish().
  uint64_t geometry = 0;
  for (const FchFrame& f : layout.frames)
    if (f.section != FchSection::Nodes) geometry += f.compressedBytes;
  EXPECT_EQ(peakSpill, geometry);
  EXPECT_EQ(dir.entries(), 1u) << "only the output is left";
}

// ---------------------------------------------------------------------------------------------
// Standard output

TEST(ClusterFileWriter, StandardOutputGivesTheFileBytesThroughAPipe) {
  ScratchDir dir("stdout");
  const auto path = dir.path / "file.fch";
  SyntheticFile reference(3000);
  ClusterFileWriter fileWriter(path, reference.info(), smallFrames());
  feed(
      fileWriter, reference, [n = 0]() mutable { return n++ % 3; }, [] { return size_t{100}; });
  fileWriter.finish();
  // The child's standard output is the pipe to this process; its spills go to `dir`.
  std::string piped;
  const int code = inChild(
      [&](int out) {
        if (::dup2(out, STDOUT_FILENO) < 0) return 1;
        SyntheticFile source(3000);
        ClusterFileWriter writer("-", source.info(), threaded(smallFrames()),
                                 dir.path);  // and in the background
        feed(
            writer, source, [n = 0]() mutable { return 2 - n++ % 3; }, [] { return size_t{77}; });
        writer.finish();
        std::fflush(stdout);
        return 0;
      },
      &piped);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(piped, slurp(path));
  EXPECT_EQ(dir.entries(), 1u) << "no spill file left";
}

// ---------------------------------------------------------------------------------------------
// Failures leave nothing behind

TEST(ClusterFileWriter, DestroyedUnfinishedLeavesNoOutputAndNoTemporaryFiles) {
  for (const bool toStdout : {false, true}) {
    ScratchDir dir("abandon");
    const auto path = toStdout ? std::filesystem::path("-") : dir.path / "never.fch";
    int64_t reported = 0;
    {
      SyntheticFile source(2000);
      ClusterFileWriter writer(path, source.info(), smallFrames(), dir.path);
      writer.setTemporaryBytesHook([&](int64_t bytes) { reported += bytes; });
      std::vector<uint32_t> indices;
      std::vector<uint64_t> ids;
      writer.addNodes(source.nodes(500));
      writer.addVertices(source.vertices(500));
      source.triangles(500, indices, ids);
      writer.addTriangles(indices, ids);
      EXPECT_GT(writer.temporaryBytesPeak(), 0u);
      EXPECT_EQ(reported, int64_t(writer.temporaryBytesPeak()));
      // Spill files are unlinked from the start: at most the output's temporary name shows.
      EXPECT_LE(dir.entries(), toStdout ? 0u : 1u);
    }
    EXPECT_EQ(dir.entries(), 0u);
    EXPECT_EQ(reported, 0) << "every spilled byte reported released";
  }
}

TEST(ClusterFileWriter, DiskFullIsAnIoErrorNamingTheFileAndLeavesNothing) {
  // The node frames (the output) or the vertex frames (a spill file) are the first to cross a
  // 256 KiB file size limit; SIGXFSZ ignored, so write() fails with EFBIG.
  for (const bool spillFirst : {false, true}) {
    ScratchDir dir("full");
    const auto path = dir.path / "full.fch";
    std::string message;
    const int code = inChild(
        [&](int out) {
          ::signal(SIGXFSZ, SIG_IGN);
          const rlimit limit{256 * 1024, 256 * 1024};
          if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) return 10;
          SyntheticFile source(40000, /*noisyVertices=*/true);  // ~480 KB of incompressible vertices
          WriteOptions options;
          options.geometryPerFrame = 1000;
          try {
            ClusterFileWriter writer(path, source.info(), options);
            feed(
                writer, source, [&, n = 0]() mutable { return n++ < 100 ? (spillFirst ? 1 : 0) : n % 3; },
                [] { return size_t{1000}; });
            writer.finish();
          } catch (const Error& e) {
            say(out, e.what());
            return 0;
          }
          return 1;
        },
        &message);
    EXPECT_EQ(code, 0) << "spill first " << spillFirst << ": " << message;
    EXPECT_EQ(message.rfind(path.string() + ": ", 0), 0u) << message;
    EXPECT_NE(message.find("File too large"), std::string::npos) << message;
    EXPECT_EQ(dir.entries(), 0u) << "no output, no temporary file";
  }
}

TEST(ClusterFileWriter, TemporaryBytesHookCanAbortTheWrite) {
  ScratchDir dir("hook");
  const auto path = dir.path / "vetoed.fch";
  for (const WriteOptions& options : {smallFrames(), threaded(smallFrames())}) {
    SyntheticFile source(5000);
    int64_t spilled = 0;
    const int64_t budget = 4000;
    {
      ClusterFileWriter writer(path, source.info(), options);
      writer.setTemporaryBytesHook([&](int64_t bytes) {
        if (spilled + bytes > budget) throw std::runtime_error("--max-tmp exceeded");
        spilled += bytes;
      });
      EXPECT_THROW(feed(
                       writer, source, [] { return 1; }, [] { return size_t{100}; }),
                   std::runtime_error);
      EXPECT_LE(spilled, budget);
      EXPECT_GT(spilled, 0);
      EXPECT_THROW(writer.addNodes(source.nodes(1)), std::logic_error) << "a failed writer refuses more";
    }
    EXPECT_EQ(spilled, 0);
    EXPECT_EQ(dir.entries(), 0u);
  }
}

std::string invalidArgument(const std::function<void()>& body) {
  try {
    body();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(ClusterFileWriter, CountsAndReferencesNotMatchingTheDeclarationAreInvalidArguments) {
  ScratchDir dir("mismatch");
  const auto path = dir.path / "bad.fch";
  const StreamFileInfo info = SyntheticFile(10).info();  // 9 nodes, 12 vertices, 10 triangles
  auto withWriter = [&](const std::function<void(ClusterFileWriter&, SyntheticFile&)>& body) {
    return invalidArgument([&] {
      SyntheticFile source(10);
      ClusterFileWriter writer(path, info, smallFrames());
      body(writer, source);
    });
  };
  auto has = [](const std::string& message, const std::string& part) {
    return message.find(part) != std::string::npos;
  };
  std::string e = withWriter([](ClusterFileWriter& w, SyntheticFile& s) {
    w.addNodes(s.nodes(9));
    w.finish();
  });
  EXPECT_TRUE(has(e, "finish: only 0 of 12 vertices, 0 of 10 triangles arrived")) << e;

  e = withWriter([](ClusterFileWriter& w, SyntheticFile& s) {
    const auto nine = s.nodes(9);
    std::vector<FchNode> nodes(nine.begin(), nine.end());
    nodes.push_back(nodes.back());
    w.addNodes(nodes);
  });
  EXPECT_TRUE(has(e, "nodes 0 ... 9 beyond the declared 9")) << e;

  e = withWriter([](ClusterFileWriter& w, SyntheticFile& s) {
    const auto nine = s.nodes(9);
    std::vector<FchNode> nodes(nine.begin(), nine.end());
    nodes[2].child[1] = 1;  // before node 2
    w.addNodes(nodes);
  });
  EXPECT_TRUE(has(e, "node 2: child 1 not after it")) << e;

  e = withWriter([](ClusterFileWriter& w, SyntheticFile& s) {
    const auto nine = s.nodes(9);
    std::vector<FchNode> nodes(nine.begin(), nine.end());
    nodes[0].childCount = 3;
    w.addNodes(nodes);
  });
  EXPECT_TRUE(has(e, "node 0: 3 children, branching factor 2")) << e;

  e = withWriter([](ClusterFileWriter& w, SyntheticFile&) {
    const uint32_t indices[] = {0, 1, 12};
    const uint64_t ids[] = {1000};
    w.addTriangles(indices, ids);
  });
  EXPECT_TRUE(has(e, "triangle 0: vertex index 12 beyond the declared 12 vertices")) << e;

  e = withWriter([](ClusterFileWriter& w, SyntheticFile&) {
    const uint32_t indices[] = {0, 1, 2, 1, 2, 3};
    const uint64_t ids[] = {1000, 1019};
    w.addTriangles(indices, ids);
  });
  EXPECT_TRUE(has(e, "triangle 1: original face id 1019 above the declared maximum 1018")) << e;

  e = withWriter([](ClusterFileWriter& w, SyntheticFile&) {
    const uint32_t indices[] = {0, 1, 2, 1};
    const uint64_t ids[] = {1000};
    w.addTriangles(indices, ids);
  });
  EXPECT_TRUE(has(e, "4 vertex indices for 1 original face ids")) << e;

  e = withWriter([](ClusterFileWriter& w, SyntheticFile&) { w.addVertices(std::vector<glm::vec3>(13)); });
  EXPECT_TRUE(has(e, "vertices 0 ... 12 beyond the declared 12")) << e;

  StreamFileInfo tooMany = info;
  tooMany.header.nodeCount = 10;
  e = invalidArgument([&] { ClusterFileWriter writer(path, tooMany); });
  EXPECT_TRUE(has(e, "10 nodes (of 10) do not fit 10 triangles")) << e;
  EXPECT_TRUE(has(e, path.string())) << e;

  EXPECT_EQ(dir.entries(), 0u);
}

TEST(ClusterFileWriter, WhatAFillMakesWrongIsRefusedFromAnyThreadAndLeavesNothing) {
  ScratchDir dir("fill_mismatch");
  const auto path = dir.path / "bad.fch";
  const ClusterFile file = SyntheticFile(10).materialize();  // 9 nodes, 12 vertices, 10 triangles
  for (const unsigned threads : {1u, 2u}) {
    WriteOptions options = smallFrames();
    options.threads = threads;
    const auto withWriter = [&](const std::function<void(ClusterFileWriter&)>& body) {
      return invalidArgument([&] {
        ClusterFileWriter writer(path, SyntheticFile(10).info(), options);
        body(writer);
        writer.finish();
      });
    };
    std::string e = withWriter([&](ClusterFileWriter& w) {
      w.addNodes(9, [&](uint64_t first, std::span<FchNode> out) {
        for (size_t i = 0; i < out.size(); ++i) {
          out[i] = file.nodes[first + i];
          if (first + i == 2) out[i].child[1] = 1;  // before node 2
        }
      });
    });
    EXPECT_NE(e.find("node 2: child 1 not after it"), std::string::npos) << e;
    EXPECT_NE(e.find(path.string()), std::string::npos) << e;

    // Triangles whose corner `badCorner` is a vertex beyond the declared ones, or whose id `badId`
    // is above the declared maximum, made by fills.
    const auto badTriangles = [&](size_t badCorner, size_t badId) {
      return withWriter([&](ClusterFileWriter& w) {
        w.addNodes(file.nodes);
        w.addVertices(file.vertices);
        w.addTriangles(
            10,
            [&](uint64_t first, std::span<uint32_t> out) {
              for (size_t i = 0; i < out.size(); ++i)
                out[i] = 3 * first + i == badCorner ? 12 : file.indices[3 * first + i];
            },
            [&](uint64_t first, std::span<uint64_t> out) {
              for (size_t i = 0; i < out.size(); ++i)
                out[i] = first + i == badId ? 1019 : file.originalFace[first + i];
            });
      });
    };
    e = badTriangles(7, SIZE_MAX);
    EXPECT_NE(e.find("triangle 2: vertex index 12 beyond the declared 12 vertices"), std::string::npos) << e;
    e = badTriangles(SIZE_MAX, 9);
    EXPECT_NE(e.find("triangle 9: original face id 1019 above the declared maximum 1018"), std::string::npos)
        << e;

    e = withWriter([](ClusterFileWriter& w) { w.addVertices(13, [](uint64_t, std::span<glm::vec3>) {}); });
    EXPECT_NE(e.find("vertices 0 ... 12 beyond the declared 12"), std::string::npos) << e;
    EXPECT_EQ(dir.entries(), 0u) << threads << " threads";
  }
}

// ---------------------------------------------------------------------------------------------
// Vertices stored more than once (out-of-core builds number vertices per leaf cluster)

TEST(ClusterFileWriter, DuplicatedVerticesVerifyCutRenderAndExportLikeUniqueOnes) {
  ScratchDir dir("duplicates");
  const TestMesh mesh = gridMesh(24, 16);
  const Hierarchy hierarchy = medianSplitHierarchy(mesh.view());
  const ClusterFile unique = makeClusterFile(mesh.view(), {}, hierarchy, {});
  // Vertices numbered by first use within runs of 17 triangles, as per-cell numbering would:
  // a vertex shared by two runs is stored twice.
  constexpr size_t kRun = 17;
  ClusterFile dup = unique;
  dup.vertices.clear();
  std::vector<uint32_t> local(unique.vertices.size());
  std::vector<size_t> stamp(unique.vertices.size(), SIZE_MAX);
  for (size_t i = 0; i < unique.indices.size(); ++i) {
    const uint32_t v = unique.indices[i];
    if (stamp[v] != i / (3 * kRun)) {
      stamp[v] = i / (3 * kRun);
      local[v] = static_cast<uint32_t>(dup.vertices.size());
      dup.vertices.push_back(unique.vertices[v]);
    }
    dup.indices[i] = local[v];
  }
  ASSERT_GT(dup.vertices.size(), unique.vertices.size() + 50);
  StreamFileInfo info;
  info.header = unique.header;
  info.header.vertexCount = dup.vertices.size();
  info.maxOriginalFace = unique.originalFace.size() - 1;
  const auto path = dir.path / "dup.fch";
  ClusterFileWriter writer(path, info);
  writer.addTriangles(dup.indices, dup.originalFace);  // geometry before nodes
  writer.addVertices(dup.vertices);
  writer.addNodes(dup.nodes);
  writer.finish();

  const ClusterFile back = readClusterFile(path);
  EXPECT_EQ(back.header.vertexCount, dup.vertices.size());
  const VerifyResult verified = verifyClusterFile(back);
  EXPECT_TRUE(verified.ok) << verified.message;
  const VerifyResult matched = verifyAgainstMesh(back, mesh.view(), {});
  EXPECT_TRUE(matched.ok) << matched.message;
  EXPECT_EQ(clusterCut(back, 40), clusterCut(unique, 40));
  EXPECT_EQ(clusterDepthCut(back, 3), clusterDepthCut(unique, 3));
  // Pictures depend on the triangles' corners only: the same pixels.
  const auto a = dir.path / "unique.png", b = dir.path / "dup.png";
  renderClustersPng(unique.mesh(), clusterCut(unique, 40), {}, a);
  renderClustersPng(back.mesh(), clusterCut(back, 40), {}, b);
  EXPECT_EQ(slurp(a), slurp(b));
  // Exports keep every stored vertex and every triangle's corners.
  const auto ply = dir.path / "dup.ply";
  writeReorderedMesh(back, ply);
  const std::string header = slurp(ply).substr(0, 200);
  EXPECT_NE(header.find("element vertex " + std::to_string(dup.vertices.size())), std::string::npos)
      << header;
  // The CLI on the same file.
  const CliResult verify = runCli("verify " + path.string());
  EXPECT_EQ(verify.exitCode, 0) << verify.out;
  const CliResult exported =
      runCli("export " + path.string() + " --cut 20 -o " + (dir.path / "cut.ply").string());
  EXPECT_EQ(exported.exitCode, 0) << exported.out;
  const CliResult rendered =
      runCli("render " + path.string() + " --width 64 --height 48 -o " + (dir.path / "cut.png").string());
  EXPECT_EQ(rendered.exitCode, 0) << rendered.out;
  const CliResult truncated =
      runCli("truncate " + path.string() + " --nodes 30 -o " + (dir.path / "t.fch").string());
  EXPECT_EQ(truncated.exitCode, 0) << truncated.out;
  EXPECT_EQ(runCli("verify " + (dir.path / "t.fch").string()).exitCode, 0);
}

}  // namespace
}  // namespace facetree
