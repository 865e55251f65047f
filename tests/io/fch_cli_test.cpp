// facetree truncate / info / verify as a user runs them.
#include <gtest/gtest.h>

#include <cstdio>
#include <sstream>

#include "../cli/run_cli.h"
#include "fch_test_util.h"

namespace facetree {
namespace {

using namespace facetree::test;

struct FchCli : ::testing::Test {
  Cleanup cleanup;
  std::filesystem::path fch = cleanup.add(scratch("cli.fch"));
  std::filesystem::path out = cleanup.add(scratch("cli_out.fch"));
  std::filesystem::path bad = cleanup.add(scratch("cli_bad.fch"));
  void SetUp() override {
    const TestMesh mesh = gridMesh(30, 20);
    FileOptions options;
    options.branching = 4;
    WriteOptions write;
    write.nodesPerFrame = 64;
    writeClusterFile(fch, makeClusterFile(mesh.view(), {}, medianSplitHierarchy(mesh.view()), options),
                     write);
  }
};

TEST_F(FchCli, InfoReportsCountsAndSections) {
  const CliResult text = runCli("info " + fch.string());
  EXPECT_EQ(text.exitCode, 0) << text.out;
  EXPECT_NE(text.out.find("1200 triangles"), std::string::npos) << text.out;
  const CliResult json = runCli("info " + fch.string() + " --json");
  EXPECT_EQ(json.exitCode, 0) << json.out;
  EXPECT_NE(json.out.find("\"branching\": 4"), std::string::npos) << json.out;
  EXPECT_NE(json.out.find("\"children_histogram\""), std::string::npos) << json.out;
}

TEST_F(FchCli, InfoFitCutsReportTheLibrarysCutFit) {
  const ClusterFile file = readClusterFile(fch);
  const CutFit one = cutFit(file, 1), some = cutFit(file, 50);
  char want[64];
  const CliResult json = runCli("info " + fch.string() + " --fit-cuts 1,50,5000 --json");
  EXPECT_EQ(json.exitCode, 0) << json.out;
  EXPECT_NE(json.out.find("\"fit_cuts\""), std::string::npos) << json.out;
  std::snprintf(want, sizeof want, "\"sum_fit\": %.9g", one.sumFit);
  EXPECT_NE(json.out.find(want), std::string::npos) << want << "\n" << json.out;
  std::snprintf(want, sizeof want, "\"sum_area_fit\": %.9g", some.sumAreaFit);
  EXPECT_NE(json.out.find(want), std::string::npos) << want << "\n" << json.out;
  EXPECT_NE(json.out.find("\"clusters\": 1200"), std::string::npos) << json.out;  // 5000 asked: every face
  std::snprintf(want, sizeof want, "\"sum_box_area\": %.9g", some.sumBoxArea);
  EXPECT_NE(json.out.find(want), std::string::npos) << want << "\n" << json.out;
  std::snprintf(want, sizeof want, "\"morton_box_area\": %.9g", some.mortonBoxArea);
  EXPECT_NE(json.out.find(want), std::string::npos) << want << "\n" << json.out;
  const CliResult text = runCli("info " + fch.string() + " --fit-cuts 50");
  EXPECT_EQ(text.exitCode, 0) << text.out;
  std::snprintf(want, sizeof want, "50 asked, %llu clusters", static_cast<unsigned long long>(some.clusters));
  EXPECT_NE(text.out.find(want), std::string::npos) << text.out;
  std::snprintf(want, sizeof want, "(%.3f x the Morton runs')", some.sumBoxArea / some.mortonBoxArea);
  EXPECT_NE(text.out.find(want), std::string::npos) << want << "\n" << text.out;
  for (const char* bad : {"0", "10,x", ",", "-5"})
    EXPECT_EQ(runCli("info " + fch.string() + " --fit-cuts " + bad).exitCode, 2) << bad;
}

TEST_F(FchCli, VerifyAcceptsGoodAndRejectsCorruptFiles) {
  const CliResult good = runCli("verify " + fch.string());
  EXPECT_EQ(good.exitCode, 0) << good.out;
  std::string bytes = slurp(fch);
  bytes[bytes.size() - 5] ^= 0x40;
  spit(bad, bytes);
  const CliResult corrupt = runCli("verify " + bad.string());
  EXPECT_EQ(corrupt.exitCode, 3) << corrupt.out;
  EXPECT_NE(corrupt.out.find("checksum mismatch"), std::string::npos) << corrupt.out;
  // A semantically broken file (a box shrunk) with valid checksums: names the node and check.
  ClusterFile file = readClusterFile(fch);
  file.nodes[5].box.halfExtent.x *= 0.5f;
  writeClusterFile(bad, file);
  const CliResult invalid = runCli("verify " + bad.string());
  EXPECT_EQ(invalid.exitCode, 3) << invalid.out;
  EXPECT_NE(invalid.out.find("node 5: box containment"), std::string::npos) << invalid.out;
}

TEST_F(FchCli, TruncateByNodesAndBytes) {
  CliResult r = runCli("truncate " + fch.string() + " -o " + out.string() + " --nodes 100");
  EXPECT_EQ(r.exitCode, 0) << r.out;
  EXPECT_EQ(readClusterFile(out).nodes.size(), 100u);
  EXPECT_EQ(runCli("verify " + out.string()).exitCode, 0);
  const uint64_t budget = std::filesystem::file_size(fch) - 2000;
  r = runCli("truncate " + fch.string() + " -o " + out.string() + " --max-bytes " + std::to_string(budget));
  EXPECT_EQ(r.exitCode, 0) << r.out;
  EXPECT_LE(std::filesystem::file_size(out), budget);
  EXPECT_EQ(runCli("verify " + out.string()).exitCode, 0);
  EXPECT_EQ(runCli("truncate " + fch.string() + " -o " + out.string()).exitCode, 2);
  EXPECT_EQ(runCli("truncate " + fch.string() + " -o " + out.string() + " --max-bytes 10").exitCode, 2);
  spit(bad, "nonsense");
  r = runCli("truncate " + bad.string() + " -o " + out.string() + " --nodes 3");
  EXPECT_EQ(r.exitCode, 3) << r.out;
  EXPECT_NE(r.out.find("not a facetree cluster file (bad magic)"), std::string::npos) << r.out;
}

// The fields of a `cut` line this test reads: "node" (-1 for null), "first", "triangles".
struct CutLine {
  int64_t node = -1;
  uint64_t first = 0, triangles = 0;
  bool hasBox = false;
};
std::vector<CutLine> cutLines(const std::string& out) {
  std::vector<CutLine> lines;
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] != '{') continue;
    CutLine c;
    const auto field = [&](const std::string& name) {
      return line.substr(line.find("\"" + name + "\":") + name.size() + 3);
    };
    const std::string node = field("node");
    c.node = node.rfind("null", 0) == 0 ? -1 : std::stoll(node);
    c.first = std::stoull(field("first"));
    c.triangles = std::stoull(field("triangles"));
    c.hasBox = line.find("\"box\":{\"center\":[") != std::string::npos;
    lines.push_back(c);
  }
  return lines;
}

TEST_F(FchCli, CutGivesTheClustersOfTheCutInFaceOrderWithTheirNodes) {
  const ClusterFile file = readClusterFile(fch);
  truncateClusterFile(fch, out, 40);
  const ClusterFile truncated = readClusterFile(out);
  for (const auto& [args, whole] : std::vector<std::pair<std::string, const ClusterFile*>>{
           {fch.string() + " --clusters 37", &file},
           {fch.string() + " --depth 3", &file},
           {fch.string() + " --max-cost 0", &file},
           {out.string() + " --clusters 1000 --memory 1M", &truncated}}) {
    SCOPED_TRACE(args);
    const CliResult r = runCli("cut " + args);
    ASSERT_EQ(r.exitCode, 0) << r.out;
    const std::vector<CutLine> lines = cutLines(r.out);
    ASSERT_FALSE(lines.empty());
    uint64_t next = 0;
    for (const CutLine& c : lines) {
      EXPECT_EQ(c.first, next);  // a partition of the face order, in order
      next += c.triangles;
      EXPECT_EQ(c.hasBox, c.node >= 0);
      if (c.node >= 0) {
        ASSERT_LT(uint64_t(c.node), whole->nodes.size());
        EXPECT_EQ(whole->nodes[c.node].first, c.first);
        EXPECT_EQ(whole->nodes[c.node].count, c.triangles);
      } else if (whole == &file) {
        EXPECT_EQ(c.triangles, 1u);  // a single face (in a truncated file, also a subtree cut off)
      }
    }
    EXPECT_EQ(next, whole->indices.size() / 3);
  }
  EXPECT_GE(cutLines(runCli("cut " + fch.string() + " --clusters 37").out).size(), 37u);
  // --max-cost 0: every node is above it, the cut is every face.
  EXPECT_EQ(cutLines(runCli("cut " + fch.string() + " --max-cost 0").out).size(), file.indices.size() / 3);
  EXPECT_EQ(cutLines(runCli("cut " + fch.string() + " --depth 0").out).size(), 1u);
  // The mesh of the cut: every face with its cluster.
  const auto mesh = cleanup.add(scratch("cli_cut.ply"));
  ASSERT_EQ(runCli("cut " + fch.string() + " --clusters 9 --mesh-out " + mesh.string()).exitCode, 0);
  const std::string ply = slurp(mesh);
  EXPECT_NE(ply.find("element face 1200\nproperty list uchar int vertex_indices\nproperty uchar red\n"
                     "property uchar green\nproperty uchar blue\nproperty uint cluster\nend_header\n"),
            std::string::npos);
  // One way to cut, and a readable file.
  CliResult r = runCli("cut " + fch.string() + " --clusters 3 --depth 2");
  EXPECT_EQ(r.exitCode, 2) << r.out;
  EXPECT_NE(r.out.find("cut needs exactly one of --clusters N, --max-cost C and --depth D"),
            std::string::npos);
  r = runCli("cut " + fch.string() + " --clusters 3 -o " + mesh.string());
  EXPECT_EQ(r.exitCode, 2) << r.out;
  EXPECT_NE(r.out.find("cut -o writes NumPy arrays: give OUT.npz, got '" + mesh.string() + "'"),
            std::string::npos)
      << r.out;
  // A .npz of a cut's arrays: members stored, the cut's clusters in them (tests/python/test_reader.py
  // reads them with NumPy).
  const auto npz = cleanup.add(scratch("cli_cut.npz"));
  ASSERT_EQ(runCli("cut " + fch.string() + " --clusters 9 -o " + npz.string()).exitCode, 0);
  const std::string arrays = slurp(npz);
  EXPECT_EQ(arrays.substr(0, 4), std::string("PK\x03\x04", 4));
  for (const char* member : {"node.npy", "first.npy", "triangles.npy", "cost.npy", "orientation.npy"})
    EXPECT_NE(arrays.find(member), std::string::npos) << member;
  const size_t clusters = cutLines(runCli("cut " + fch.string() + " --clusters 9").out).size();
  EXPECT_NE(arrays.find("{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(clusters) +
                        ", 4), }"),
            std::string::npos);
  r = runCli("cut " + fch.string() + " --max-cost nan");
  EXPECT_EQ(r.exitCode, 2) << r.out;
  EXPECT_NE(r.out.find("--max-cost needs a finite number, got 'nan'"), std::string::npos) << r.out;
  // A record whose cost is NaN (found by fuzz_fch_reader; its checksums are sound): every reader
  // names it, and the commands exit 3.
  const std::string nan =
      std::string(FACETREE_TEST_DATA) + "/../fuzz/corpus/fuzz_fch_reader/regress_nan_cost.fch";
  for (const char* command : {"info ", "verify ", "cut --clusters 5 "}) {
    r = runCli(std::string(command) + nan);
    EXPECT_EQ(r.exitCode, 3) << command << r.out;
    EXPECT_NE(r.out.find(nan + ": node frame 0 (nodes 0-20): node 1: cost, area or perimeter not finite"),
              std::string::npos)
        << command << r.out;
  }
  spit(bad, "nonsense");
  r = runCli("cut " + bad.string() + " --clusters 3");
  EXPECT_EQ(r.exitCode, 3) << r.out;
  EXPECT_NE(r.out.find(bad.string() + ": not a facetree cluster file (bad magic)"), std::string::npos)
      << r.out;
}

}  // namespace
}  // namespace facetree
