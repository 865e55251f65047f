// fuzz_fch: the cluster file reader (readClusterFile, readClusterFileLayout) and verify.
// readClusterFile takes a path, so the bytes go to a memfd (no file on disk) opened through
// /proc/self/fd. Every input is read twice: as given, and with its checksums recomputed
// (header, index, frames) so that mutations reach the field checks and the frame decoders
// instead of stopping at a checksum mismatch (make_fch_seeds.py writes seeds whose frames are
// stored zstd blocks, so mutated payloads stay decompressible). Error (Input) and
// std::invalid_argument are the documented errors; anything else crashes. A file that reads
// and verifies must also give its statistics and cuts.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "facetree/io.h"
#include "fuzz_fch_file.h"
#include "io/format/fch_format.h"

using namespace facetree;

namespace {

using namespace facetree::fuzz;

void readAndVerify(const std::string& path) {
  try {
    (void)readClusterFileLayout(path);
  } catch (const Error& e) {
    checkMessage(e.what());
    return;  // the whole-file reads fail the same way
  }
  try {
    const ClusterFile nodesOnly = readClusterFile(path, /*geometry=*/false);
    (void)verifyClusterFile(nodesOnly);
  } catch (const Error& e) {
    checkMessage(e.what());
  }
  ClusterFile file;
  try {
    file = readClusterFile(path);
  } catch (const Error& e) {
    checkMessage(e.what());
    return;
  }
  const VerifyResult result = verifyClusterFile(file);
  if (!result.ok) return;
  try {
    (void)branchingStats(file);
    const std::vector<uint32_t> cut = clusterCut(file, 16);
    if (cut.size() != file.indices.size() / 3) fail("clusterCut: not one cluster per face");
    const std::vector<uint32_t> depthCut = clusterDepthCut(file, 3);
    if (depthCut.size() != file.indices.size() / 3) fail("clusterDepthCut: not one cluster per face");
    if (!file.nodes.empty()) {
      // A prefix of the nodes is a valid hierarchy (docs/FORMAT.md "Truncation").
      ClusterFile prefix = file;
      truncateInMemory(prefix, (file.nodes.size() + 1) / 2);
      const VerifyResult truncated = verifyClusterFile(prefix);
      if (!truncated.ok) fail("verified file truncated in memory fails verify: " + truncated.message);
    }
  } catch (const std::invalid_argument&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static MemFile file;
  readAndVerify(file.write(data, size));
  std::vector<uint8_t> fixed(data, data + size);
  fixChecksums(fixed);
  if (fixed.size() >= fch::kHeaderBytes && std::memcmp(fixed.data(), data, size) != 0)
    readAndVerify(file.write(fixed.data(), fixed.size()));
  return 0;
}
