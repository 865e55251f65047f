// ClusterFileWriter: the .fch layout of docs/FORMAT.md written piece by piece, holding one frame
// per section; writeClusterFile feeds it a whole ClusterFile (one code path, same bytes).
//
// Layout while writing (file output): [header + index placeholder][node frames ...] in the
// output's temporary file, vertex / triangle / id frames in three spill files. finish() appends
// the spills in section order and overwrites the placeholder, whose size is known from the
// declared counts (every frame but a section's last is full). Standard output cannot seek, so
// there the node frames are spilled too and everything goes out in finish().
#include <algorithm>
#include <limits>
#include <optional>
#include <stdexcept>
#include <thread>
#include <unordered_map>
#include <utility>

#include <glm/common.hpp>

#include "facetree/io.h"
#include "facetree/storage.h"
#include "format/fch_format.h"
#include "format/node_code.h"
#include "format/piece.h"

namespace facetree {
namespace {

using fch::kMaxGeometryPerFrame;
using fch::kMaxNodesPerFrame;

constexpr size_t kCopyBufferBytes = size_t{1} << 20;    // spill -> output copies
constexpr size_t kOutputBufferBytes = size_t{1} << 20;  // OutputFile's stdio buffer
// Compression threads at most (WriteOptions::threads): frames are small and independent.
constexpr unsigned kMaxCompressorThreads = 8;
// Frames queued or in flight per worker. One: a second would keep a worker busy while the caller
// waits for the oldest frame, for a frame's buffers more per worker (out of core, under the cap).
constexpr unsigned kSlotsPerWorker = 1;
// Nodes a fill makes at a time for an exact-box frame: their records stay in cache until quantised.
constexpr uint32_t kFillChunk = 256;

// The compressor pool's workers for WriteOptions::threads (0: the hardware's); none for one thread,
// which compresses inline.
unsigned compressorThreads(const WriteOptions& options) {
  const unsigned threads = options.threads ? options.threads : std::thread::hardware_concurrency();
  return threads > 1 ? std::min(threads, kMaxCompressorThreads) : 0;
}
constexpr size_t kSections = 4;

size_t slot(FchSection section) {
  return static_cast<size_t>(section) - 1;
}
uint64_t framesFor(uint64_t elements, uint32_t perFrame) {
  return (elements + perFrame - 1) / perFrame;
}
std::string str(uint64_t v) {
  return std::to_string(v);
}

// A section's spilled frames into the output, in order.
void copySpill(const TemporaryFile& spill, uint64_t bytes, OutputFile& out, std::vector<char>& buffer) {
  for (uint64_t offset = 0; offset < bytes;) {
    const size_t n = static_cast<size_t>(std::min<uint64_t>(buffer.size(), bytes - offset));
    spill.read(offset, buffer.data(), n);
    out.write(buffer.data(), n);
    offset += n;
  }
}

// Adds `n` elements from `first` as a fill makes them, through a scratch vector.
template <class T, class Fill, class Add>
auto throughScratch(std::vector<T>& scratch, const Fill& fill, Add add) {
  return [&scratch, &fill, add](uint64_t first, size_t n) {
    scratch.resize(n);
    fill(first, scratch);
    add(scratch);
  };
}

// A worker's buffers, reused frame to frame: elements made by a fill, node codes.
struct FrameScratch {
  std::vector<FchNode> nodes;
  std::vector<fch::NodeCode> codes;
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> corners;
  std::vector<uint64_t> ids;
};

// The vertex bounds of a frame made on a worker, folded into the header when the frame is placed
// (min and max do not depend on the order).
struct Bounds {
  glm::vec3 lo{std::numeric_limits<float>::infinity()}, hi{-std::numeric_limits<float>::infinity()};
  void add(std::span<const glm::vec3> points) {
    for (const glm::vec3& p : points) lo = glm::min(lo, p), hi = glm::max(hi, p);
  }
};

// Makes a frame's payload into `raw`: from the node records handed to the frame (`given`; exact-box
// node frames) or from a fill, with a worker's scratch.
using FrameMaker = std::function<void(std::span<const fch::NodeCode> given, FrameScratch& scratch,
                                      std::string& raw, Bounds& bounds)>;

// Appends the codes of nodes first, first + 1, ... with exact boxes: each record depends on its
// node alone, so workers can make them. `owner` prefixes the message of a node the format cannot hold.
void quantizeExact(std::span<const FchNode> nodes, uint64_t first, const std::string& owner,
                   std::vector<fch::NodeCode>& codes) {
  try {
    for (size_t i = 0; i < nodes.size(); ++i)
      codes.push_back(fch::quantizeNode(nodes[i], first + i, BoxPrecision::Exact, nullptr, nullptr));
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(owner + ": " + e.what());
  }
}

// A frame compressed on a worker (WriteOptions::threads > 1) with the worker's own compressor and
// scratch (a frame with a maker: the worker makes its payload too). The caller takes the frames back
// in turn and writes each where it goes, so frames land in order, compressed exactly as inline (each
// frame is independent): the same bytes for any number of workers. A frame's buffers stay with its
// slot of the ring, so their capacity serves the frames after it.
struct FrameJob {
  FchSection section{};
  uint64_t first = 0;
  uint32_t count = 0;
  std::string raw;
  std::vector<fch::NodeCode> codes;  // handed to `make`
  FrameMaker make;                   // empty: `raw` is the payload
  Bounds bounds;
  std::string compressed;
  FchFrame frame{};
};

}  // namespace

struct ClusterFileWriter::State {
  // One section's progress: elements arrived, frames written (offsets relative to the section's
  // start until finish()), compressed bytes, and the unnamed file holding them (none for file-output
  // nodes), which the kernel frees when the writer goes, however the process ends.
  struct Section {
    uint64_t declared = 0;
    uint64_t arrived = 0;
    uint64_t bytes = 0;
    std::vector<FchFrame> frames;
    std::optional<TemporaryFile> spill;
  };

  std::string name;        // the output as named in messages
  std::string writerName;  // "ClusterFileWriter NAME", for messages made on the pool's workers
  std::filesystem::path spillDir;
  FchLayout layout;
  uint64_t maxOriginalFace = 0;
  uint64_t nodeLimit = 0;   // node child references below this (originalNodeCount: cut-off children)
  uint64_t frontBytes = 0;  // header + index
  fch::FrameCompressor compressor;
  std::vector<std::unique_ptr<fch::FrameCompressor>> workerCompressors;  // the pool's, one a worker
  std::vector<FrameScratch> workerScratch;
  // WriteOptions::threads > 1: compresses instead of `compressor`. Frame makers on its workers read
  // only the members above it, which outlive it.
  std::optional<HelperRing<FrameJob>> pool;
  std::optional<OutputFile> output;  // file output: from the start; a stream: in finish()
  bool stream = false;               // isStreamOutput: the header cannot be written last
  std::optional<PieceRange> piece;   // WriteOptions::piece: every frame spilled, a piece file written
  Section sections[kSections];
  std::vector<fch::NodeCode> codes;       // a node run's records (addNodeRun)
  std::vector<fch::NodeCode> frameCodes;  // the node frame being gathered
  // Compact boxes: the decoded boxes of the parents of nodes still to come, by child index.
  std::unordered_map<uint32_t, NodeBox> parentBoxes;
  bool hasRoot = false;  // the root arrived (compact boxes: its box is layout.rootBox)
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> indices;
  std::vector<uint64_t> ids;
  std::string compressed;  // reused for every frame
  FrameScratch scratch;    // frames made on this thread: one thread, or a fill's head and tail
  std::string raw;         // their payload
  uint64_t spilled = 0, spilledPeak = 0;
  std::function<void(int64_t)> hook;
  bool finished = false, failed = false;

  State(const std::filesystem::path& out, const StreamFileInfo& info, const WriteOptions& options,
        const std::filesystem::path& tmpDir);
  Section& section(FchSection s) { return sections[slot(s)]; }
  uint32_t perFrame(FchSection s) const {
    return s == FchSection::Nodes ? layout.nodesPerFrame : layout.geometryPerFrame;
  }
  [[noreturn]] void reject(const std::string& what) const {
    throw std::invalid_argument("ClusterFileWriter " + name + ": " + what);
  }
  // Section `s`, about to take `count` more of its elements (`what`): refuses more than declared.
  Section& arriving(FchSection s, const char* what, size_t count) {
    Section& sec = section(s);
    if (count > sec.declared - sec.arrived)
      reject(std::string(what) + " " + str(sec.arrived) + " ... " + str(sec.arrived + count - 1) +
             " beyond the declared " + str(sec.declared));
    return sec;
  }
  void checkNode(const FchNode& node, uint64_t index) const;
  void writeFrame(FchSection s, uint64_t first, uint32_t count, std::string&& raw);
  // A frame whose payload `make` makes (on a worker when there are workers) from `given`.
  void makeFrame(FchSection s, uint64_t first, uint32_t count, FrameMaker make,
                 std::span<const fch::NodeCode> given = {});
  // The pool's next frame, once a slot is free; its payload `raw`, or made by `make`.
  void submit(FchSection s, uint64_t first, uint32_t count, std::string* raw, FrameMaker make = {},
              std::span<const fch::NodeCode> given = {});
  // Places a compressed frame: in the output (file-output nodes) or its section's spill.
  void placeFrame(FchSection s, FchFrame frame, std::string_view bytes, const Bounds& bounds);
  // Places the pool's oldest frame (waiting for it), or every frame still in the pool.
  void placeOldest();
  void drain();
  // A record for the frame being gathered, which goes to a worker once whole.
  void pushCode(const fch::NodeCode& code);
  void vertexFrame(std::span<const glm::vec3> batch);
  void triangleFrames(std::span<const uint32_t> corners, std::span<const uint64_t> faces);
  void addNodes(std::span<const FchNode> nodes);
  // Compact boxes: the decoded box of node `index`'s parent into `box` (false for the root), refused
  // when no earlier node refers to it; keepParentBox holds a node's box for its node child `child`.
  bool takeParentBox(uint64_t index, NodeBox& box);
  void keepParentBox(uint32_t child, const NodeBox& box);
  void addVertices(std::span<const glm::vec3> vertices);
  void addTriangles(std::span<const uint32_t> indices, std::span<const uint64_t> originalFace);
  void checkTriangles(std::span<const uint32_t> indices, std::span<const uint64_t> originalFace,
                      uint64_t first) const;
  // Frames of `count` elements made by `make(first, n)`, from the section's arrival on: the
  // elements completing a frame begun by earlier ones, and those short of a frame at the end that
  // is not the section's, go through `add(first, n)` on this thread.
  template <class Add, class Make>
  void fillFrames(FchSection s, size_t buffered, uint64_t count, Add&& add, Make&& make);
  void release(Section& s);
  // Every entry point: refuses a writer that failed or finished, and marks it failed if the call
  // throws (its buffers and files are then in no defined state).
  template <class Body>
  auto guarded(const char* call, Body&& body) {
    if (failed || finished)
      throw std::logic_error(std::string("ClusterFileWriter::") + call + ": the writer has " +
                             (failed ? "failed" : "finished"));
    try {
      return body();
    } catch (...) {
      failed = true;
      throw;
    }
  }
};

ClusterFileWriter::State::State(const std::filesystem::path& out, const StreamFileInfo& info,
                                const WriteOptions& options, const std::filesystem::path& tmpDir)
    : name(out.string()),
      writerName("ClusterFileWriter " + name),
      compressor(options.zstdLevel, info.header.boxes) {
  if (const unsigned workers = compressorThreads(options)) {
    for (unsigned w = 0; w < workers; ++w)
      workerCompressors.push_back(
          std::make_unique<fch::FrameCompressor>(options.zstdLevel, info.header.boxes));
    workerScratch.resize(workers);
    const auto compress = [this](FrameJob& job, unsigned w) {
      if (job.make) job.make(job.codes, workerScratch[w], job.raw, job.bounds);
      job.frame = workerCompressors[w]->compress(job.section, job.first, job.count, job.raw, job.compressed);
    };
    pool.emplace(compress, kSlotsPerWorker * workers, workers);
  }
  if (options.nodesPerFrame < 1 || options.nodesPerFrame > kMaxNodesPerFrame)
    reject("nodesPerFrame " + str(options.nodesPerFrame) + " out of range 1 ... " + str(kMaxNodesPerFrame));
  if (options.geometryPerFrame < 1 || options.geometryPerFrame > kMaxGeometryPerFrame)
    reject("geometryPerFrame " + str(options.geometryPerFrame) + " out of range 1 ... " +
           str(kMaxGeometryPerFrame));
  layout = fch::startLayout(info, options);
  FileHeader& h = layout.header;
  if (h.branching < 2 || h.branching > kMaxBranching)
    reject("branching factor " + str(h.branching) + " out of range 2 ... 8");
  if (h.triangleCount > fch::kMaxTriangles) reject("too many triangles: " + str(h.triangleCount));
  if (h.originalNodeCount > std::max<uint64_t>(h.triangleCount, 1) - 1 ||
      (h.triangleCount >= 2) != (h.nodeCount >= 1))
    reject(str(h.nodeCount) + " nodes (of " + str(h.originalNodeCount) + ") do not fit " +
           str(h.triangleCount) + " triangles (a root for 2 or more, at most one fewer than the triangles)");
  if (h.vertexCount > 3 * h.triangleCount)
    reject(str(h.vertexCount) + " vertices for " + str(h.triangleCount) +
           " triangles (at most 3 per triangle)");
  nodeLimit = h.originalNodeCount;
  maxOriginalFace = info.maxOriginalFace;

  section(FchSection::Nodes).declared = h.nodeCount;
  section(FchSection::Vertices).declared = h.vertexCount;
  section(FchSection::Triangles).declared = h.triangleCount;
  section(FchSection::OriginalFaces).declared = h.triangleCount;
  uint64_t frames = 0;
  for (const FchSection s :
       {FchSection::Nodes, FchSection::Vertices, FchSection::Triangles, FchSection::OriginalFaces}) {
    section(s).frames.reserve(framesFor(section(s).declared, perFrame(s)));
    frames += framesFor(section(s).declared, perFrame(s));
  }
  if (frames > std::numeric_limits<uint32_t>::max()) reject("too many frames: " + str(frames));
  frontBytes = fch::kHeaderBytes + uint64_t{fch::kIndexEntryBytes} * frames;

  piece = options.piece;
  if (piece) {
    const PieceRange& r = *piece;
    const auto startAt = [&](FchSection sec, uint64_t first, uint64_t end) {
      if (first > end || end > section(sec).declared || first % perFrame(sec) != 0 ||
          (end % perFrame(sec) != 0 && end != section(sec).declared))
        reject(std::string("piece: ") + sectionName(sec) + " " + str(first) + " ... " + str(end) +
               " not on frame boundaries of " + str(section(sec).declared));
      section(sec).arrived = first;
      section(sec).declared = end;
    };
    startAt(FchSection::Nodes, r.firstNode, r.endNode);
    startAt(FchSection::Vertices, r.firstVertex, r.endVertex);
    startAt(FchSection::Triangles, r.firstTriangle, r.endTriangle);
    startAt(FchSection::OriginalFaces, r.firstTriangle, r.endTriangle);
  }
  stream = isStreamOutput(out);
  spillDir = !tmpDir.empty()         ? tmpDir
             : stream                ? std::filesystem::temp_directory_path()
             : out.has_parent_path() ? out.parent_path()
                                     : std::filesystem::path(".");
  if (!stream && !piece) {
    // Header and index are known last: a placeholder of their exact size, overwritten by finish().
    output.emplace(out);
    const std::string zeros(static_cast<size_t>(std::min<uint64_t>(frontBytes, kCopyBufferBytes)), '\0');
    for (uint64_t done = 0; done < frontBytes; done += zeros.size())
      output->write(zeros.data(), static_cast<size_t>(std::min<uint64_t>(zeros.size(), frontBytes - done)));
  }
}

void ClusterFileWriter::State::checkNode(const FchNode& node, uint64_t index) const {
  const uint64_t end = uint64_t{node.first} + node.count;
  if (node.childCount > layout.header.branching)
    reject("node " + str(index) + ": " + str(node.childCount) + " children, branching factor " +
           str(layout.header.branching));
  if (end > layout.header.triangleCount)
    reject("node " + str(index) + ": faces " + str(node.first) + " ... " + str(end) +
           " beyond the declared " + str(layout.header.triangleCount) + " triangles");
  for (unsigned c = 0; c < node.childCount; ++c) {
    const uint32_t ref = node.child[c];
    if (ref & kFaceChild) {
      const uint32_t position = ref & ~kFaceChild;
      if (position < node.first || position >= end)
        reject("node " + str(index) + ": face child " + str(position) + " outside its faces " +
               str(node.first) + " ... " + str(end));
    } else if (ref <= index || ref >= nodeLimit) {
      reject("node " + str(index) + ": child " + str(ref) + " not after it among the declared " +
             str(nodeLimit) + " nodes");
    }
  }
}

void ClusterFileWriter::State::writeFrame(FchSection s, uint64_t first, uint32_t count, std::string&& raw) {
  if (pool) return submit(s, first, count, &raw);
  const FchFrame frame =
      compressor.compress(s, first, count, raw, compressed);  // before `compressed` is read
  placeFrame(s, frame, compressed, Bounds{});
}

void ClusterFileWriter::State::makeFrame(FchSection s, uint64_t first, uint32_t count, FrameMaker make,
                                         std::span<const fch::NodeCode> given) {
  if (pool) return submit(s, first, count, nullptr, std::move(make), given);
  Bounds bounds;
  make(given, scratch, raw, bounds);
  const FchFrame frame = compressor.compress(s, first, count, raw, compressed);
  placeFrame(s, frame, compressed, bounds);
}

void ClusterFileWriter::State::submit(FchSection s, uint64_t first, uint32_t count, std::string* raw,
                                      FrameMaker make, std::span<const fch::NodeCode> given) {
  if (pool->full()) placeOldest();
  FrameJob& job = pool->slot();
  job.section = s, job.first = first, job.count = count;
  if (raw) job.raw = std::move(*raw);
  job.codes.assign(given.begin(), given.end());
  job.make = std::move(make);
  job.bounds = Bounds{};
  pool->submit();
}

void ClusterFileWriter::State::placeOldest() {
  const FrameJob& done = pool->take();
  placeFrame(done.section, done.frame, done.compressed, done.bounds);
}

void ClusterFileWriter::State::drain() {
  while (pool && !pool->empty()) placeOldest();
}

void ClusterFileWriter::State::placeFrame(FchSection s, FchFrame frame, std::string_view bytes,
                                          const Bounds& bounds) {
  Section& sec = section(s);
  FileHeader& h = layout.header;
  h.boundsMin = glm::min(h.boundsMin, bounds.lo);
  h.boundsMax = glm::max(h.boundsMax, bounds.hi);
  frame.offset = sec.bytes;
  if (s == FchSection::Nodes && !stream && !piece) {
    output->write(bytes);
  } else {
    if (hook) hook(static_cast<int64_t>(bytes.size()));
    spilled += bytes.size();  // counted once the hook agreed, released whatever happens next
    spilledPeak = std::max(spilledPeak, spilled);
    if (!sec.spill) sec.spill.emplace(spillDir, name);
    sec.spill->write(sec.bytes, bytes.data(), bytes.size());
  }
  sec.bytes += bytes.size();
  sec.frames.push_back(frame);
}

void ClusterFileWriter::State::vertexFrame(std::span<const glm::vec3> batch) {
  const uint64_t first = section(FchSection::Vertices).arrived - batch.size();
  std::string out;
  fch::encodeVertices(batch, out);
  writeFrame(FchSection::Vertices, first, static_cast<uint32_t>(batch.size()), std::move(out));
}
void ClusterFileWriter::State::triangleFrames(std::span<const uint32_t> corners,
                                              std::span<const uint64_t> faces) {
  const uint64_t first = section(FchSection::Triangles).arrived - faces.size();
  const auto n = static_cast<uint32_t>(faces.size());
  std::string out;
  fch::encodeTriangles(corners, out);
  writeFrame(FchSection::Triangles, first, n, std::move(out));
  std::exchange(out, {});
  fch::encodeIds(faces, layout.originalIdBytes, out);
  writeFrame(FchSection::OriginalFaces, first, n, std::move(out));
}

void ClusterFileWriter::State::release(Section& s) {
  if (!s.spill) return;
  const uint64_t bytes = s.bytes;
  s.spill.reset();
  spilled -= bytes;
  if (hook) hook(-static_cast<int64_t>(bytes));
}

namespace {

// Feeds `items` to a section frame by frame: a full frame (or the section's last) straight from
// the caller's span when nothing is buffered, else through `buffer`. `emit` sees each frame's
// elements after `arrived` counts them.
template <class T, class Emit>
void appendFrames(std::span<const T> items, std::vector<T>& buffer, uint64_t& arrived, uint64_t declared,
                  uint32_t perFrame, Emit&& emit) {
  while (!items.empty()) {
    // Elements that complete the current frame: full, or the section's end.
    const uint64_t frameEnd = std::min<uint64_t>(declared, (arrived - buffer.size()) + perFrame);
    const size_t need = static_cast<size_t>(frameEnd - arrived);
    const size_t take = std::min(need, items.size());
    if (buffer.empty() && take == need) {
      arrived += take;
      emit(items.first(take));
    } else {
      buffer.insert(buffer.end(), items.begin(), items.begin() + static_cast<ptrdiff_t>(take));
      arrived += take;
      if (take == need) {
        emit(std::span<const T>(buffer));
        buffer.clear();
      }
    }
    items = items.subspan(take);
  }
}

}  // namespace

ClusterFileWriter::ClusterFileWriter(const std::filesystem::path& out, const StreamFileInfo& info,
                                     const WriteOptions& options, const std::filesystem::path& tmpDir)
    : state_(std::make_unique<State>(out, info, options, tmpDir)) {}

ClusterFileWriter::~ClusterFileWriter() {
  if (!state_ || state_->finished || !state_->hook || state_->spilled == 0) return;
  try {
    state_->hook(-static_cast<int64_t>(state_->spilled));
  } catch (...) {  // a destructor reports, it does not throw
  }
}

void ClusterFileWriter::State::pushCode(const fch::NodeCode& code) {
  Section& sec = section(FchSection::Nodes);
  frameCodes.push_back(code);
  ++sec.arrived;
  const uint64_t first = sec.arrived - frameCodes.size();
  const auto n = static_cast<uint32_t>(frameCodes.size());
  if (n < std::min<uint64_t>(layout.nodesPerFrame, sec.declared - first)) return;
  makeFrame(
      FchSection::Nodes, first, n,
      [precision = layout.header.boxes](std::span<const fch::NodeCode> given, FrameScratch&, std::string& raw,
                                        Bounds&) { fch::encodeNodeFrame(given, precision, raw); },
      frameCodes);
  frameCodes.clear();
}

bool ClusterFileWriter::State::takeParentBox(uint64_t index, NodeBox& box) {
  if (index == 0) return false;
  const auto it = parentBoxes.find(static_cast<uint32_t>(index));
  if (it == parentBoxes.end()) reject("node " + str(index) + ": no earlier node refers to it");
  box = it->second;
  parentBoxes.erase(it);
  return true;
}

void ClusterFileWriter::State::keepParentBox(uint32_t child, const NodeBox& box) {
  if (child < layout.header.nodeCount) parentBoxes.emplace(child, box);
}

void ClusterFileWriter::State::addNodes(std::span<const FchNode> batch) {
  Section& sec = arriving(FchSection::Nodes, "nodes", batch.size());
  for (size_t i = 0; i < batch.size(); ++i) checkNode(batch[i], sec.arrived + i);
  if (frameCodes.capacity() == 0) frameCodes.reserve(std::min<uint64_t>(layout.nodesPerFrame, sec.declared));
  const BoxPrecision precision = layout.header.boxes;
  for (const FchNode& node : batch) {
    const uint64_t index = sec.arrived;
    try {
      if (precision == BoxPrecision::Exact) {  // quantised here: frames take records of any origin
        pushCode(fch::quantizeNode(node, index, BoxPrecision::Exact, nullptr, nullptr));
        continue;
      }
      // Compact boxes: against the parent's box as decoded, in file order.
      NodeBox parent, decoded;
      const bool hasParent = takeParentBox(index, parent);
      pushCode(fch::quantizeNode(node, index, precision, hasParent ? &parent : nullptr, &decoded));
      if (!hasParent) layout.rootBox = decoded, hasRoot = true;
      for (unsigned c = 0; c < node.childCount; ++c)
        if (!(node.child[c] & kFaceChild)) keepParentBox(node.child[c], decoded);
    } catch (const std::invalid_argument& e) {
      reject(e.what());
    }
  }
}

void ClusterFileWriter::State::addVertices(std::span<const glm::vec3> batch) {
  Section& sec = arriving(FchSection::Vertices, "vertices", batch.size());
  FileHeader& h = layout.header;
  for (const glm::vec3& p : batch)
    h.boundsMin = glm::min(h.boundsMin, p), h.boundsMax = glm::max(h.boundsMax, p);
  if (vertices.capacity() == 0) vertices.reserve(std::min<uint64_t>(layout.geometryPerFrame, sec.declared));
  appendFrames(batch, vertices, sec.arrived, sec.declared, layout.geometryPerFrame,
               [&](std::span<const glm::vec3> frame) { vertexFrame(frame); });
}

void ClusterFileWriter::State::checkTriangles(std::span<const uint32_t> corners,
                                              std::span<const uint64_t> faces, uint64_t first) const {
  const uint64_t vertexCount = layout.header.vertexCount;
  for (size_t i = 0; i < corners.size(); ++i)
    if (corners[i] >= vertexCount)
      reject("triangle " + str(first + i / 3) + ": vertex index " + str(corners[i]) +
             " beyond the declared " + str(vertexCount) + " vertices");
  for (size_t i = 0; i < faces.size(); ++i)
    if (faces[i] > maxOriginalFace)
      reject("triangle " + str(first + i) + ": original face id " + str(faces[i]) +
             " above the declared maximum " + str(maxOriginalFace));
}

void ClusterFileWriter::State::addTriangles(std::span<const uint32_t> corners,
                                            std::span<const uint64_t> faces) {
  if (corners.size() != 3 * faces.size())
    reject(str(corners.size()) + " vertex indices for " + str(faces.size()) +
           " original face ids (3 per triangle)");
  Section& sec = arriving(FchSection::Triangles, "triangles", faces.size());
  checkTriangles(corners, faces, sec.arrived);
  const uint32_t g = layout.geometryPerFrame;
  if (ids.capacity() == 0) {
    ids.reserve(std::min<uint64_t>(g, sec.declared));
    indices.reserve(3 * ids.capacity());
  }
  // Triangles and ids share their framing: walk both by triangles, through one buffer pair.
  uint64_t arrived = sec.arrived;
  while (!faces.empty()) {
    const uint64_t frameEnd = std::min<uint64_t>(sec.declared, (arrived - ids.size()) + g);
    const size_t need = static_cast<size_t>(frameEnd - arrived);
    const size_t take = std::min(need, faces.size());
    arrived += take;
    sec.arrived = section(FchSection::OriginalFaces).arrived = arrived;
    if (ids.empty() && take == need) {
      triangleFrames(corners.first(3 * take), faces.first(take));
    } else {
      ids.insert(ids.end(), faces.begin(), faces.begin() + static_cast<ptrdiff_t>(take));
      indices.insert(indices.end(), corners.begin(), corners.begin() + static_cast<ptrdiff_t>(3 * take));
      if (take == need) {
        triangleFrames(indices, ids);
        ids.clear();
        indices.clear();
      }
    }
    faces = faces.subspan(take);
    corners = corners.subspan(3 * take);
  }
}

template <class Add, class Make>
void ClusterFileWriter::State::fillFrames(FchSection s, size_t buffered, uint64_t count, Add&& add,
                                          Make&& make) {
  Section& sec = arriving(s, sectionName(s), count);
  const uint32_t per = perFrame(s);
  uint64_t first = sec.arrived;
  const uint64_t end = first + count;
  if (buffered > 0) {  // complete the frame begun
    const uint64_t head = std::min(end, std::min<uint64_t>(sec.declared, first - buffered + per)) - first;
    add(first, static_cast<size_t>(head));
    first += head;
  }
  while (first < end) {
    const uint64_t frameEnd = std::min<uint64_t>(sec.declared, first + per);
    if (frameEnd > end) {  // short of a frame: buffered until more comes
      add(first, static_cast<size_t>(end - first));
      break;
    }
    make(first, static_cast<uint32_t>(frameEnd - first));
    first = frameEnd;
  }
}

void ClusterFileWriter::addNodes(std::span<const FchNode> nodes) {
  State& s = *state_;
  s.guarded("addNodes", [&] { s.addNodes(nodes); });
}

void ClusterFileWriter::addNodes(uint64_t count, NodeFill fill) {
  State& s = *state_;
  s.guarded("addNodes", [&] {
    const auto add = throughScratch(s.scratch.nodes, fill, [&](const auto& nodes) { s.addNodes(nodes); });
    // Compact boxes are quantised against their parents' in file order, on this thread.
    const bool onWorkers = s.layout.header.boxes == BoxPrecision::Exact;
    const size_t buffered = s.frameCodes.size();
    s.fillFrames(FchSection::Nodes, buffered, count, add, [&](uint64_t first, uint32_t n) {
      if (!onWorkers) return add(first, n);
      s.section(FchSection::Nodes).arrived += n;
      // Made kFillChunk nodes at a time, so that the nodes are still in cache when quantised.
      s.makeFrame(FchSection::Nodes, first, n,
                  [&s, fill, first, n](std::span<const fch::NodeCode>, FrameScratch& scratch,
                                       std::string& raw, Bounds&) {
                    scratch.codes.clear();
                    for (uint32_t at = 0; at < n; at += kFillChunk) {
                      scratch.nodes.resize(std::min(kFillChunk, n - at));
                      fill(first + at, scratch.nodes);
                      for (size_t i = 0; i < scratch.nodes.size(); ++i)
                        s.checkNode(scratch.nodes[i], first + at + i);
                      quantizeExact(scratch.nodes, first + at, s.writerName, scratch.codes);
                    }
                    fch::encodeNodeFrame(scratch.codes, BoxPrecision::Exact, raw);
                  });
    });
  });
}

void ClusterFileWriter::addNodeRun(std::string_view run, size_t n, uint64_t runFirst,
                                   const std::function<uint32_t(uint64_t)>& childIndex, BoxPrecision records,
                                   size_t skip, size_t take) {
  State& s = *state_;
  s.guarded("addNodeRun", [&] {
    if (records == BoxPrecision::Compact && s.layout.header.boxes != BoxPrecision::Compact)
      s.reject("addNodeRun: compact records in a file of exact boxes");
    // Exact-box records in a compact-box file: quantised here against the parents' decoded boxes.
    const bool compact = s.layout.header.boxes == BoxPrecision::Compact && records == BoxPrecision::Exact;
    if (skip > n) s.reject("addNodeRun: skips " + str(skip) + " of a run of " + str(n));
    take = std::min(take, n - skip);
    if (compact && (skip > 0 || take < n))
      s.reject("addNodeRun: part of a run of exact records in a compact-box file");
    State::Section& sec = s.arriving(FchSection::Nodes, "nodes", take);
    std::vector<fch::NodeCode>& codes = s.codes;
    codes.clear();
    if (std::string error = fch::decodeNodeFrame(run, n, records, s.layout.header.branching, codes);
        !error.empty())
      s.reject("node run: " + error);
    for (size_t i = skip; i < skip + take; ++i) {
      fch::NodeCode& code = codes[i];
      const uint64_t index = sec.arrived;
      if (index == 0 && records == BoxPrecision::Compact)
        s.reject("node 0: the root's box goes in the header (add the root as a node or an exact-box run)");
      for (unsigned k = 0; k < code.refCount; ++k) {
        const uint64_t target = childIndex(runFirst + i + code.ref[k]);
        if (target <= index || target >= s.nodeLimit)
          s.reject("node " + str(index) + ": child " + str(target) + " not after it among the declared " +
                   str(s.nodeLimit) + " nodes");
        code.ref[k] = static_cast<uint32_t>(target - index);
      }
      if (compact) {
        NodeBox parent, decoded;
        const bool hasParent = s.takeParentBox(index, parent);
        if (std::string error = fch::compactRunRecord(code, index, hasParent ? &parent : nullptr, decoded);
            !error.empty())
          s.reject("node " + str(index) + ": " + error);
        if (!hasParent) s.layout.rootBox = decoded, s.hasRoot = true;
        for (unsigned k = 0; k < code.refCount; ++k)
          s.keepParentBox(static_cast<uint32_t>(index + code.ref[k]), decoded);
      }
      s.pushCode(code);
    }
  });
}

void ClusterFileWriter::addParentBox(uint64_t child, const NodeBox& decoded) {
  State& s = *state_;
  s.guarded("addParentBox", [&] { s.keepParentBox(static_cast<uint32_t>(child), decoded); });
}

void ClusterFileWriter::addVertices(std::span<const glm::vec3> vertices) {
  State& s = *state_;
  s.guarded("addVertices", [&] { s.addVertices(vertices); });
}

void ClusterFileWriter::addVertices(uint64_t count, VertexFill fill) {
  State& s = *state_;
  s.guarded("addVertices", [&] {
    const auto add =
        throughScratch(s.scratch.vertices, fill, [&](const auto& vertices) { s.addVertices(vertices); });
    s.fillFrames(FchSection::Vertices, s.vertices.size(), count, add, [&](uint64_t first, uint32_t n) {
      s.section(FchSection::Vertices).arrived += n;
      s.makeFrame(FchSection::Vertices, first, n,
                  [fill, first, n](std::span<const fch::NodeCode>, FrameScratch& scratch, std::string& raw,
                                   Bounds& bounds) {
                    scratch.vertices.resize(n);
                    fill(first, scratch.vertices);
                    bounds.add(scratch.vertices);
                    fch::encodeVertices(scratch.vertices, raw);
                  });
    });
  });
}

void ClusterFileWriter::addTriangles(std::span<const uint32_t> indices,
                                     std::span<const uint64_t> originalFace) {
  State& s = *state_;
  s.guarded("addTriangles", [&] { s.addTriangles(indices, originalFace); });
}

void ClusterFileWriter::addTriangles(uint64_t count, IndexFill indices, IdFill originalFace) {
  State& s = *state_;
  s.guarded("addTriangles", [&] {
    const auto add = [&](uint64_t first, size_t n) {
      s.scratch.corners.resize(3 * n);
      s.scratch.ids.resize(n);
      indices(first, s.scratch.corners);
      originalFace(first, s.scratch.ids);
      s.addTriangles(s.scratch.corners, s.scratch.ids);
    };
    s.fillFrames(FchSection::Triangles, s.ids.size(), count, add, [&](uint64_t first, uint32_t n) {
      s.section(FchSection::Triangles).arrived += n;
      s.section(FchSection::OriginalFaces).arrived += n;
      s.makeFrame(FchSection::Triangles, first, n,
                  [&s, indices, first, n](std::span<const fch::NodeCode>, FrameScratch& scratch,
                                          std::string& raw, Bounds&) {
                    scratch.corners.resize(3 * size_t{n});
                    indices(first, scratch.corners);
                    s.checkTriangles(scratch.corners, {}, first);
                    fch::encodeTriangles(scratch.corners, raw);
                  });
      s.makeFrame(FchSection::OriginalFaces, first, n,
                  [&s, originalFace, first, n](std::span<const fch::NodeCode>, FrameScratch& scratch,
                                               std::string& raw, Bounds&) {
                    scratch.ids.resize(n);
                    originalFace(first, scratch.ids);
                    s.checkTriangles({}, scratch.ids, first);
                    fch::encodeIds(scratch.ids, s.layout.originalIdBytes, raw);
                  });
    });
  });
}

uint64_t ClusterFileWriter::finish() {
  State& s = *state_;
  return s.guarded("finish", [&] {
    s.drain();  // a frame made wrong on a worker is the first error
    std::string missing;
    for (const FchSection section : {FchSection::Nodes, FchSection::Vertices, FchSection::Triangles}) {
      const State::Section& sec = s.section(section);
      if (sec.arrived != sec.declared)
        missing += std::string(missing.empty() ? "" : ", ") + str(sec.arrived) + " of " + str(sec.declared) +
                   " " + sectionName(section);
    }
    if (!missing.empty()) s.reject("finish: only " + missing + " arrived");

    FchLayout& layout = s.layout;
    if (s.piece) {
      fch::PieceTrailer trailer;
      trailer.range = *s.piece;
      trailer.boundsMin = layout.header.boundsMin;
      trailer.boundsMax = layout.header.boundsMax;
      trailer.hasRoot = s.hasRoot && layout.header.boxes == BoxPrecision::Compact;
      trailer.rootBox = layout.rootBox;
      uint64_t offset = 0;
      for (State::Section& sec : s.sections) {
        for (FchFrame& f : sec.frames) trailer.frames.push_back(f), trailer.frames.back().offset += offset;
        offset += sec.bytes;
      }
      s.output.emplace(s.name);
      std::vector<char> buffer(kCopyBufferBytes);
      for (State::Section& sec : s.sections) {
        if (sec.spill) copySpill(*sec.spill, sec.bytes, *s.output, buffer);
        s.release(sec);
      }
      s.output->write(fch::encodePieceTrailer(trailer));
      const uint64_t bytes = s.output->bytesWritten();
      s.output->commit();
      s.finished = true;
      return bytes;
    }
    FileHeader& h = layout.header;
    if (h.vertexCount == 0) h.boundsMin = h.boundsMax = glm::vec3(0.0f);
    uint64_t offset = s.frontBytes;
    layout.frames.clear();
    for (State::Section& sec : s.sections) {
      for (FchFrame& f : sec.frames) layout.frames.push_back(f), layout.frames.back().offset += offset;
      offset += sec.bytes;
    }
    layout.fileBytes = offset;
    const std::string front = fch::encodeHeaderAndIndex(layout);
    std::vector<char> buffer(kCopyBufferBytes);
    if (s.stream) {
      s.output.emplace(s.name);
      s.output->write(front);
    }
    for (State::Section& sec : s.sections) {
      if (sec.spill) copySpill(*sec.spill, sec.bytes, *s.output, buffer);
      s.release(sec);
    }
    if (!s.stream) s.output->writeAt(0, front);
    if (s.output->bytesWritten() != layout.fileBytes)
      throw std::logic_error("ClusterFileWriter: wrote " + str(s.output->bytesWritten()) +
                             " bytes, expected " + str(layout.fileBytes));
    s.output->commit();
    s.finished = true;
    return layout.fileBytes;
  });
}

uint64_t ClusterFileWriter::temporaryBytesPeak() const {
  return state_->spilledPeak;
}

void ClusterFileWriter::setTemporaryBytesHook(std::function<void(int64_t)> hook) {
  state_->hook = std::move(hook);
}

uint64_t writerMemoryBound(const WriteOptions& options) {
  const uint64_t n = options.nodesPerFrame, g = options.geometryPerFrame;
  const uint64_t nodeRaw = (fch::nodeFixedBytes(BoxPrecision::Exact) + 4 * (2 * kMaxBranching - 1)) * n;
  // Per section: the element buffer, the payload and the compressed frame (zstd's bound); for
  // nodes also their codes and the column scratch.
  const uint64_t nodes = (sizeof(FchNode) + 2 * sizeof(fch::NodeCode)) * n + 4 * kMaxBranching * n + nodeRaw +
                         fch::compressedBound(nodeRaw);
  const uint64_t vertices = sizeof(glm::vec3) * g + 12 * g + fch::compressedBound(12 * g);
  const uint64_t triangles = 12 * g + 12 * g + fch::compressedBound(12 * g);
  const uint64_t ids = 8 * g + 8 * g + fch::compressedBound(8 * g);
  const uint64_t largestRaw = std::max(nodeRaw, 12 * g);
  // Frames made from fills: the elements, node codes and payload of one frame, on this thread and
  // on each worker.
  const uint64_t scratch = (sizeof(FchNode) + sizeof(fch::NodeCode)) * n + (12 + 12 + 8) * g + largestRaw;
  // In the pool: per slot a frame's nodes, payload and compressed bytes; per worker a scratch and
  // a compressor.
  const uint64_t workers = compressorThreads(options);
  const uint64_t background =
      kSlotsPerWorker * workers *
          (sizeof(fch::NodeCode) * n + largestRaw + fch::compressedBound(largestRaw)) +
      workers * (scratch + fch::compressorMemoryBound(options.zstdLevel, largestRaw));
  return nodes + vertices + triangles + ids + scratch +
         fch::compressorMemoryBound(options.zstdLevel, largestRaw) + background + kCopyBufferBytes +
         kOutputBufferBytes + 64 * 1024;  // + the header, index entry vectors, names
}

void writeClusterFile(const std::filesystem::path& path, const ClusterFile& file,
                      const WriteOptions& options) {
  const uint64_t triangles = file.indices.size() / 3;
  if (file.indices.size() % 3 != 0)
    throw std::invalid_argument("writeClusterFile: " + str(file.indices.size()) +
                                " vertex indices do not make whole triangles");
  if (file.originalFace.size() != triangles)
    throw std::invalid_argument("writeClusterFile: one original face id per triangle expected");
  StreamFileInfo info;
  info.header = file.header;
  info.header.nodeCount = file.nodes.size();
  info.header.triangleCount = triangles;
  info.header.vertexCount = file.vertices.size();
  for (const uint64_t id : file.originalFace) info.maxOriginalFace = std::max(info.maxOriginalFace, id);
  ClusterFileWriter writer(path, info, options);
  // Through fills, so that the writer's workers quantise the nodes as they compress them.
  writer.addNodes(file.nodes.size(), [&file](uint64_t first, std::span<FchNode> out) {
    std::copy_n(file.nodes.begin() + static_cast<ptrdiff_t>(first), out.size(), out.begin());
  });
  writer.addVertices(file.vertices);
  writer.addTriangles(file.indices, file.originalFace);
  writer.finish();
}

}  // namespace facetree
