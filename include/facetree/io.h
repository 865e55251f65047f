// facetree/io: writes and reads what the merge produced. Public header of the module: std, glm
// and the merge's header only.
//
// - The cluster file (.fch): a face cluster hierarchy with its reordered geometry; writing it
//   whole or piece by piece, reading it back, truncation (Willmott 2000, sec. 5.5.3),
//   verification, cuts and their fit. The byte layout is documented in docs/FORMAT.md.
// - Recasting a binary hierarchy to a larger branching factor (sec. 5.5.1).
// - Mesh writers (PLY, STL, Draco) and the output file every writer goes through; a cut as NumPy
//   arrays. Pictures are facetree/picture.h, synthetic meshes facetree/generate.h.
//
// Errors: reading a cluster file that is unreadable, corrupt or of an unsupported version throws
// facetree::Error of category Input ("FILE: REASON"); writers throw category Output naming the
// file; std::invalid_argument for inconsistent arguments; nothing else except std::bad_alloc.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/ext/vector_uint3_sized.hpp>
#include <glm/vec3.hpp>

#include "facetree/error.h"
#include "facetree/merge.h"

namespace facetree {

// --- The cluster file ----------------------------------------------------------------------

// The format version this library writes and reads (docs/FORMAT.md).
inline constexpr uint32_t kFchVersion = 2;
// The largest branching factor a cluster file holds.
inline constexpr unsigned kMaxBranching = 8;

// Node flags as stored (bits 0, 1 = merge.h NodeFlag) and derived on read (bit 2).
enum FchNodeFlag : uint8_t {
  kFchJoinsDisjointSurfaces = 1u << 0,
  kFchFlatFrame = 1u << 1,
  kFchTruncated = 1u << 2,  // some child was cut off by truncation: set by the reader, never stored
};

// Header fields other than the layout (counts of what the file holds and the options used).
struct FileHeader {
  uint32_t version = kFchVersion;              // of the format (docs/FORMAT.md)
  uint64_t nodeCount = 0;                      // nodes in the file
  uint64_t originalNodeCount = 0;              // before truncation
  uint64_t triangleCount = 0;                  // triangles (faces) in the file
  uint64_t vertexCount = 0;                    // vertices in the file
  uint32_t branching = 2;                      // most children a node has: 2, 4 or 8
  Metric metric = Metric::Willmott;            // the build's options, recorded
  double k = 0;                                // BuildOptions::k
  double flatThreshold = 0;                    // BuildOptions::flatThreshold
  double garlandWeights[3] = {1, 1, 1};        // fit, dir, shape
  uint64_t memoryCapBytes = 0;                 // 0 = not given
  glm::vec3 boundsMin{0.0f}, boundsMax{0.0f};  // of the vertices
  // How boxes are stored (version 2; version 1 files read as Exact): BuildOptions::boxes.
  BoxPrecision boxes = BoxPrecision::Exact;
  uint32_t topClusters = 0;  // BuildOptions::topClusters (version 2; 0 in version 1 files)
};

// One node. A child reference is a node index (>= nodes.size() means cut off by truncation) or
// kFaceChild | face position; children are in face-range order and partition [first, first+count).
struct FchNode {
  uint32_t first = 0, count = 0;       // its faces: positions [first, first + count) of the face order
  uint8_t childCount = 0;              // 2 to the file's branching
  uint8_t flags = 0;                   // FchNodeFlag bits
  uint32_t child[kMaxBranching] = {};  // childCount references, in face-range order
  // Faces under each child (1 for a face child): the writers need them with the node, since a node
  // child's own record comes later; readers fill them in.
  uint32_t childFaces[kMaxBranching] = {};
  float cost = 0;                 // as Node::cost
  float area = 0, perimeter = 0;  // of the cluster's surface and its boundary
  glm::vec3 sumNormal{0.0f};      // S = sum of area-weighted face normals; projArea = |S|
  NodeBox box{};                  // the oriented box of the node's faces, with their projected side areas
};

// A whole cluster file in memory: header, nodes in file order and the reordered mesh.
struct ClusterFile {
  FileHeader header;                   // counts and the build's options
  std::vector<FchNode> nodes;          // root first; every child after its parent
  std::vector<glm::vec3> vertices;     // numbered by first use along `indices`
  std::vector<uint32_t> indices;       // 3 per triangle, triangles in hierarchy order
  std::vector<uint64_t> originalFace;  // per triangle: face index in the input mesh file
  MeshView mesh() const { return {vertices, indices}; }
  bool isCutOff(uint32_t childRef) const { return !(childRef & kFaceChild) && childRef >= nodes.size(); }
};

// How the binary hierarchy is grouped into b-ary nodes (sec. 5.5.1). Either way every b-ary node
// is a binary node and its children are the leaves of a binary subtree rooted there.
enum class RecastRule : uint8_t {
  // Top down: expand the frontier node of largest area until b children (balanced groups).
  LargestArea,
  // Bottom up (Kundu & Misra 1977): the fewest b-ary nodes any grouping can reach; groups near
  // the leaves are full, the root's may be small.
  FewestNodes,
};

// How a hierarchy becomes a cluster file: branching, recast rule, options recorded.
struct FileOptions {
  uint32_t branching = 2;                     // 2 ... kMaxBranching (sec. 5.5.1: 4 and 8 are the useful ones)
  RecastRule rule = RecastRule::LargestArea;  // how binary nodes are grouped into b-ary ones
  BuildOptions build;                         // recorded in the header
  uint64_t memoryCapBytes = 0;                // recorded in the header
};

// The header fields that record the build's options (the counts are the writer's to fill in).
FileHeader optionsHeader(const FileOptions& options);

// Recast statistics (sec. 5.5.1).
struct BranchingStats {
  uint32_t branching = 2;                                    // b
  uint64_t triangles = 0;                                    // faces, the tree's leaves
  uint64_t internalNodes = 0;                                // nodes of the file
  double eq85Nodes = 0;                                      // (n - 1) / (b - 1), the full-b-ary count
  std::array<uint64_t, kMaxBranching + 1> childHistogram{};  // nodes by number of children
  uint32_t height = 0;          // nodes on the longest root-to-face path, faces included
  uint32_t balancedHeight = 0;  // eq. 86: ceil(log n / log b) + 1

  bool operator==(const BranchingStats&) const = default;
};

// The cluster file of a binary hierarchy of `mesh` recast to options.branching. `originalFace`
// maps each triangle of `mesh` (buildHierarchy's input order) to its face in the mesh file;
// empty means the identity. Boxes are copied from the binary nodes (a b-ary node is a binary
// node with the same face range); the hierarchy must have them (BuildOptions::computeBoxes).
// Throws std::invalid_argument for an inconsistent hierarchy.
ClusterFile makeClusterFile(const MeshView& mesh, std::span<const uint64_t> originalFace,
                            const Hierarchy& hierarchy, const FileOptions& options,
                            BranchingStats* stats = nullptr);
// Statistics of the tree in `file` (children histogram, height, eq. 85/86).
BranchingStats branchingStats(const ClusterFile& file);
// The same statistics of the file `hierarchy` makes under `options`, without making it.
BranchingStats branchingStats(const Hierarchy& hierarchy, const FileOptions& options);

// The cluster file's default zstd level, tuned for its byte planes (FrameCompressor).
inline constexpr int kDefaultZstdLevel = 3;

// How a cluster file is written: frame sizes, zstd level, compression threads.
// The elements a piece of a cluster file holds: [first, end) of each section, the original ids
// with their triangles (ClusterFileWriter with WriteOptions::piece, assembleClusterFile).
struct PieceRange {
  uint64_t firstNode = 0, endNode = 0;
  uint64_t firstVertex = 0, endVertex = 0;
  uint64_t firstTriangle = 0, endTriangle = 0;
};
struct WriteOptions {
  uint32_t nodesPerFrame = 4096;      // truncation recompresses at most this many nodes
  uint32_t geometryPerFrame = 65536;  // vertices / triangles / ids per frame
  int zstdLevel = kDefaultZstdLevel;  // higher: a few percent smaller, several times slower
  // 2 or more (0: the hardware's count): each frame is compressed on a helper thread while the
  // caller encodes the next one (zstd is ~60% of a write); 1: on the calling thread. The bytes are
  // the same either way.
  unsigned threads = 1;
  // A piece of the file: the writer takes only these elements, in order, and finish() writes a
  // piece file (their frames and index entries) at its output instead of a cluster file. Each
  // range starts on a frame boundary and ends on one or at its section's end.
  std::optional<PieceRange> piece = std::nullopt;
};
// Writes atomically (temporary name + rename). Same input, same bytes. A ClusterFileWriter fed
// the whole file: the bytes of any other writer given the same elements.
void writeClusterFile(const std::filesystem::path& path, const ClusterFile& file,
                      const WriteOptions& options = {});

// Writes a cluster file piece by piece (docs/FORMAT.md): the header's counts are declared up front, then
// nodes (file order), vertices (file order) and triangles with their original face ids (hierarchy order) are
// appended, the three streams in any interleaving. Node frames go straight to their place in the output (the
// index size is known from the counts); vertex, triangle and id frames are spilled, already compressed, to
// temporary files in `tmpDir` (default: the output's directory) and appended by finish(). Output "-" is
// standard output, and an existing output that is not a regular file (a named pipe, a device) is written in
// place the same way (isStreamOutput): node frames are spilled too and everything is streamed by
// finish(); bytes go out only in finish(). Any other output is written to a temporary name and renamed by
// finish(); a writer destroyed without finish() removes its temporary files and leaves no output. Memory: one
// frame of each section plus the zstd context. Throws Error (Output) naming the file for write failures
// (disk full...), std::invalid_argument for counts or references that do not match the declaration (checked
// as they come and in finish()).
//
// Details: spill files are unlinked as soon as they are created (nothing is left behind even on
// SIGKILL; their space is freed when the writer goes); with output "-" and no tmpDir they go to
// std::filesystem::temp_directory_path(). The same elements give the same bytes however they are
// batched. After any exception the writer can only be destroyed (other calls: std::logic_error).
// Memory bound: writerMemoryBound(options).
struct StreamFileInfo {
  FileHeader header;  // nodeCount, triangleCount, vertexCount, branching, metric, k, ... (bounds: ignored,
                      // computed from the vertices); originalNodeCount = nodeCount
  uint64_t maxOriginalFace = 0;  // largest original face id to come: decides 4- or 8-byte ids
};
// Writes a cluster file piece by piece (see above).
class ClusterFileWriter {
 public:
  ClusterFileWriter(const std::filesystem::path& out, const StreamFileInfo& info,
                    const WriteOptions& options = {}, const std::filesystem::path& tmpDir = {});
  ~ClusterFileWriter();
  ClusterFileWriter(const ClusterFileWriter&) = delete;
  ClusterFileWriter& operator=(const ClusterFileWriter&) = delete;
  void addNodes(
      std::span<const FchNode> nodes);  // children: absolute file indices, or kFaceChild | face position
  void addVertices(std::span<const glm::vec3> vertices);
  void addTriangles(std::span<const uint32_t> indices,
                    std::span<const uint64_t> originalFace);  // 3 indices each
  // The same elements made on demand, a frame at a time, on the writer's workers (WriteOptions::threads;
  // inline with one thread): fill(first, out) writes elements first ... first + out.size() - 1, and may run
  // on several threads at once; elements that complete a frame begun by earlier ones, or fall short of a
  // frame before the section's end, are made on the calling thread. What a fill reads must stay valid
  // until the writer finishes or is destroyed. Checked as the elements are made; same bytes as the
  // elements added in spans, in any mix with them.
  using NodeFill = std::function<void(uint64_t first, std::span<FchNode> out)>;
  using VertexFill = std::function<void(uint64_t first, std::span<glm::vec3> out)>;
  using IndexFill = std::function<void(uint64_t firstTriangle, std::span<uint32_t> out)>;  // 3 per triangle
  using IdFill = std::function<void(uint64_t firstTriangle, std::span<uint64_t> out)>;
  void addNodes(uint64_t count, NodeFill fill);
  // `n` nodes as encodeNodeRun encoded them (nodes runFirst, runFirst + 1, ... of their own tree),
  // appended without quantising them again: their records unchanged but for their node children's
  // references (childIndex(i) is the file index of the node the run's tree calls i; face children
  // and face ranges follow from the parents'). With compact boxes, exact-box records (`records`
  // Exact) have their boxes quantised here against their parents' as decoded, which the writer keeps
  // until each child arrives; records that compactNodeRun made (`records` Compact) are taken as
  // they are. References are checked as addNodes checks them.
  // Nodes skip ... skip + take - 1 of the run only, when a piece starts or ends inside it (exact
  // boxes, or compact records).
  void addNodeRun(std::string_view run, size_t n, uint64_t runFirst,
                  const std::function<uint32_t(uint64_t)>& childIndex,
                  BoxPrecision records = BoxPrecision::Exact, size_t skip = 0,
                  size_t take = std::numeric_limits<size_t>::max());
  // A piece of a compact-box file: the decoded box of the parent of node `child`, which another
  // piece holds (compactDecodedBox gives it).
  void addParentBox(uint64_t child, const NodeBox& decoded);
  void addVertices(uint64_t count, VertexFill fill);
  void addTriangles(uint64_t count, IndexFill indices, IdFill originalFace);
  uint64_t finish();                    // returns the file size; all counts must have arrived
  uint64_t temporaryBytesPeak() const;  // bytes of spilled frames at their largest
  // Called with +bytes / -bytes whenever spilled bytes grow or shrink (so the caller can enforce --max-tmp);
  // may throw, which aborts the write cleanly. +bytes comes before the frame is spilled; -bytes when a
  // spill file is released (in finish(), or by the destructor of an unfinished writer, which ignores
  // exceptions then): the hook must outlive the writer.
  void setTemporaryBytesHook(std::function<void(int64_t)> hook);

 private:
  struct State;
  std::unique_ptr<State> state_;
};
// The cluster file of `pieces` (ClusterFileWriter piece files, in any order) that together hold
// every element `info` declares, written atomically at `out`: the bytes one writer given the same
// elements would write, the frames copied as they are. `options` as the pieces' writers had them.
// Throws Error (Input) naming a piece file that is not one, or pieces that leave a gap or overlap.
uint64_t assembleClusterFile(const std::filesystem::path& out, const StreamFileInfo& info,
                             const WriteOptions& options, std::span<const std::filesystem::path> pieces);

// The same file assembled by several tasks: beginClusterFile reads the pieces' trailers, writes the
// header and index at `partial` (its full size, the frames still to come) and says where each
// piece's frames go; placePieces copies some of them there (each task its own share, synced);
// once every copy is placed, commitClusterFile gives `partial` its name `out`. The bytes of
// assembleClusterFile.
struct PieceCopy {
  uint32_t piece = 0;                    // index in the pieces given to beginClusterFile
  uint64_t from = 0, to = 0, bytes = 0;  // offset in the piece, offset in the file, length
};
struct ClusterFileAssembly {
  uint64_t fileBytes = 0;
  std::vector<PieceCopy> copies;  // every frame, consecutive frames of a piece merged
};
ClusterFileAssembly beginClusterFile(const std::filesystem::path& partial, const StreamFileInfo& info,
                                     const WriteOptions& options,
                                     std::span<const std::filesystem::path> pieces);
void placePieces(const std::filesystem::path& partial, std::span<const std::filesystem::path> pieces,
                 std::span<const PieceCopy> copies);
void commitClusterFile(const std::filesystem::path& partial, const std::filesystem::path& out);

// Upper bound of the bytes a ClusterFileWriter holds (buffers of one frame per section, their
// payloads and compressed forms, the zstd context, the output buffer), whatever the counts; the
// frame index adds 40 bytes per frame. Compact boxes add the decoded box of every node whose
// parent has arrived and which has not (BoxPrecision::Compact quantises a box against its parent's).
uint64_t writerMemoryBound(const WriteOptions& options = {});

// Runs of nodes in the file's version 2 record encoding (docs/FORMAT.md), for nodes that wait on disk
// before they are written (the out-of-core build's spills, ClusterFileWriter::addNodeRun): nodes
// firstIndex, firstIndex + 1, ... of a tree whose children come after their parents, face children in
// face-range order (as written). As in the file, face ranges are not stored; orientations are on
// `precision`'s lattice, boxes as exact boxes store them (extents rounded outwards by at most 2^-17),
// S and side areas as the file does. Throws std::invalid_argument for a node the format cannot hold
// (quantizeNode's reasons).
std::string encodeNodeRun(std::span<const FchNode> nodes, uint64_t firstIndex, BoxPrecision precision);
// Compact boxes of a tree placed in pieces (docs/FORMAT.md: a child's box is quantised against its
// parent's as decoded, so it depends on its ancestors only): the box a compact-box file decodes for
// a node whose exact box is `box` (orientation on the compact lattice) under a parent decoded as
// `parent` (null: the root, which the header stores as it is). Throws std::logic_error when the box
// does not fit its parent's.
NodeBox compactDecodedBox(const NodeBox& box, const NodeBox* parent);
// An encodeNodeRun run of compact-lattice nodes (nodes runFirst ... of their tree) as the records of
// a compact-box file: each box quantised against `parentBox[i]`, the decoded box of tree node i's
// parent, which the caller sets for the tree's root and this sets for the run's node children.
// Runs of one tree go in tree order. Throws std::runtime_error for bytes that are not such a run.
std::string compactNodeRun(std::string_view run, size_t n, uint64_t runFirst, std::span<NodeBox> parentBox);

// makeClusterFile's file streamed into a ClusterFileWriter at `path` without building the ClusterFile:
// every frame's nodes and geometry are made from the hierarchy and the mesh by the writer's workers
// (fills), vertices numbered by first use beforehand (two indices per input vertex are held). For
// b = 2 the recast is the identity and no tree is built. Same bytes as
// writeClusterFile(path, makeClusterFile(...), writeOptions). Returns the file size; `stats`, when
// given, gets the file's branchingStats.
uint64_t writeClusterFile(const std::filesystem::path& path, const MeshView& mesh,
                          std::span<const uint64_t> originalFace, const Hierarchy& hierarchy,
                          const FileOptions& options, const WriteOptions& writeOptions = {},
                          BranchingStats* stats = nullptr);

// Reads and checks (checksums, sizes, index ranges) a whole file through a ClusterFileReader
// (below) under the cap the file was built under; `geometry` false skips the vertex, triangle and
// id frames (their checksums are not checked then).
ClusterFile readClusterFile(const std::filesystem::path& path, bool geometry = true);

// The sections a cluster file's frames belong to, and their names.
enum class FchSection : uint32_t { Nodes = 1, Vertices = 2, Triangles = 3, OriginalFaces = 4 };
const char* sectionName(FchSection section);
// One compressed frame of the frame index: its section, its elements and where its bytes are.
struct FchFrame {
  FchSection section{};                        // what the frame holds
  uint32_t count = 0;                          // elements (nodes, vertices, triangles or ids) in the frame
  uint64_t first = 0;                          // index in its section of the frame's first element
  uint64_t offset = 0;                         // where its compressed bytes start in the file
  uint32_t compressedBytes = 0, rawBytes = 0;  // its size in the file, and decompressed
  uint64_t checksum = 0;                       // XXH64 of the raw (decompressed) bytes
};
// A cluster file's header and frame index, as readClusterFileLayout reads them.
struct FchLayout {
  FileHeader header;         // as readClusterFile reads it
  uint64_t fileBytes = 0;    // the file's size
  uint32_t headerBytes = 0;  // the header and frame index, before the first frame
  // Elements per frame: nodes in a node frame; vertices, triangles or ids in the others.
  uint32_t nodesPerFrame = 0, geometryPerFrame = 0;
  uint32_t originalIdBytes = 0;  // 4, or 8 when an input face id exceeds 32 bits
  int zstdLevel = 0;             // the level the frames were compressed at
  std::vector<FchFrame> frames;  // in file order
  NodeBox rootBox{};             // compact boxes: the root's centre and half extents, from the header
};
// Header and frame index only (validated; frame contents are not read).
FchLayout readClusterFileLayout(const std::filesystem::path& path);

// --- Reading under a memory cap ---------------------------------------------------------------
// A cluster file read lazily: opening reads the header and the frame index only; node records and
// geometry are decoded frame by frame as asked, every frame checked (checksum, sizes, references)
// before use, with the errors readClusterFile gives. Version 2 derives a node's face range and depth
// (and a compact box) from its parent's record, so node frames decode in file order: what a pass
// holds is the children its nodes announced and not yet reached (at most a quarter of the nodes in
// the middle of a file, past its share of memory in a temporary file), and decoded frames wait in a
// cache.

// The triangles of a range of the face order with their own vertex numbering.
struct FaceRangeMesh {
  uint64_t first = 0;                  // the range's first face position
  std::vector<glm::vec3> vertices;     // the vertices the triangles use, in the file's vertex order
  std::vector<uint32_t> indices;       // 3 per triangle, into `vertices`
  std::vector<uint64_t> originalFace;  // per triangle: its face index in the input mesh file
  std::vector<uint64_t> vertexIds;     // per vertex: its index in the file
};

// One cluster of a cut: a node's whole face range, a single face, or a gap that cut-off children of
// a truncated file leave (one cluster per gap, as clusterCut counts them).
inline constexpr uint64_t kNoNode = ~uint64_t{0};
struct CutCluster {
  uint64_t node = kNoNode;  // the node whose range it is; kNoNode for a face or a gap
  uint64_t first = 0;       // face positions [first, first + count)
  uint64_t count = 0;
};

// How much a reader holds: a quarter of memoryBytes caches decoded frames, a quarter holds a pass's
// announced children (the rest go to a temporary file in `tmp`), the rest is left to the caller's
// use of what it reads and to the process.
struct ReaderOptions {
  uint64_t memoryBytes = 0;   // 0: the cap the file was built under, else defaultMemoryCap()
  std::filesystem::path tmp;  // empty: the system's temporary directory
};
// Half the RAM: the default cap of a build and of a reader of a file built without one.
uint64_t defaultMemoryCap();

// What a pass over the nodes decodes: every field, or the tree alone (face ranges, children, flags,
// cost, area and perimeter; S and the box left zero), which skips the boxes' decoding.
enum class NodeFields : uint8_t { All, Structure };
// What a face range decodes: every field, or the triangles and their vertices alone (the original
// ids' frames are not read).
enum class FaceFields : uint8_t { All, Geometry };

namespace fch {
struct ReaderAccess;
}

class ClusterFileReader {
 public:
  explicit ClusterFileReader(const std::filesystem::path& path, const ReaderOptions& options = {});
  // A file already open (a descriptor handed over by a parent, a sandbox): a regular file, read
  // through a duplicate of `fd` at offsets; the caller keeps and closes `fd`. `name` stands for
  // the file in errors.
  ClusterFileReader(int fd, const std::string& name, const ReaderOptions& options = {});
  ~ClusterFileReader();
  ClusterFileReader(const ClusterFileReader&) = delete;
  ClusterFileReader& operator=(const ClusterFileReader&) = delete;

  const FchLayout& layout() const;
  const FileHeader& header() const;
  uint64_t size() const;  // nodes
  // The cap it holds (ReaderOptions::memoryBytes resolved) and where its temporary files go.
  uint64_t memoryBytes() const;
  const std::filesystem::path& temporaryDirectory() const;
  // The file as its messages name it (the path, or the name given with a descriptor).
  const std::string& name() const;

  // Node `index` (< size()). In file order each node frame decodes once; a frame that has left the
  // cache decodes again with the frames before it.
  FchNode node(uint64_t index);
  // The records of node frame `frame` (< the frames of layout(); nodes frame * nodesPerFrame on),
  // as node() decodes them.
  std::vector<FchNode> nodeFrame(uint64_t frame);
  // Calls visit(index, node, depth) for nodes 0, 1, ... (depth: the root's is 1) until it returns
  // false or the nodes end; one pass that caches nothing. Returns the nodes visited.
  uint64_t forEachNode(const std::function<bool(uint64_t, const FchNode&, uint32_t)>& visit,
                       NodeFields fields = NodeFields::All);

  // The cut of at least `clusters` clusters from the shortest node prefix (as clusterCut), in face
  // order.
  std::vector<CutCluster> cut(uint64_t clusters);
  // The cut under the nodes whose effective cost (the largest cost in their subtree) exceeds
  // `maxCost`: the shortest prefix of the file that holds them.
  std::vector<CutCluster> cutByCost(double maxCost);
  // The cut under the nodes of depth below `depth` (the root's is 1): clusterDepthCut's clusters.
  std::vector<CutCluster> cutByDepth(uint32_t depth);

  // The triangles of face positions [first, first + count): only the geometry frames they touch
  // (FaceFields::Geometry: not the original ids', and originalFace stays empty).
  FaceRangeMesh faces(uint64_t first, uint64_t count, FaceFields fields = FaceFields::All);
  // Calls visit(cluster, mesh) for the clusters of `cut` in face order.
  void forEachCluster(std::span<const CutCluster> cut,
                      const std::function<void(const CutCluster&, const FaceRangeMesh&)>& visit);
  // The triangles of a cut (which covers every face, in face order, as the cuts above give it) in
  // pieces of at most one triangle frame, in face order: visit(piece, clusterOf), clusterOf[t] the
  // position in `cut` of the cluster holding the piece's triangle t. Each triangle and id frame is
  // decoded once in the pass.
  void forEachCutPiece(std::span<const CutCluster> cut,
                       const std::function<void(const FaceRangeMesh&, std::span<const uint32_t>)>& visit,
                       FaceFields fields = FaceFields::All);
  // Every triangle of the file in face order, in pieces of one triangle frame (as forEachCutPiece,
  // without a cut).
  void forEachFacePiece(const std::function<void(const FaceRangeMesh&)>& visit,
                        FaceFields fields = FaceFields::All);
  // The file's vertices in order, a vertex frame at a time: visit(first vertex index, positions).
  void forEachVertexFrame(const std::function<void(uint64_t, std::span<const glm::vec3>)>& visit);
  // The file's triangles in face order, a triangle frame at a time, as stored: visit(first face
  // position, corners in the file's vertex numbering (3 per triangle), original ids (empty with
  // FaceFields::Geometry)).
  void forEachTriangleFrame(
      const std::function<void(uint64_t, std::span<const uint32_t>, std::span<const uint64_t>)>& visit,
      FaceFields fields = FaceFields::All);

  // Bytes the reader holds now (caches, the index, the node() pass's announced children), the most
  // any pass held, and what passes wrote to temporary files.
  uint64_t heldBytes() const;
  uint64_t peakHeldBytes() const;
  uint64_t spilledBytes() const;

 private:
  friend struct fch::ReaderAccess;  // the frames as stored, for copying them (truncation)
  struct State;
  std::unique_ptr<State> state_;
};

// branchingStats of a file read in one pass of its nodes.
BranchingStats branchingStats(ClusterFileReader& reader);
// A version 1 node's childFaces, which its record does not hold (readers fill them in): a kept node
// child's is its own count, rangeOf(child) giving that child's (first, count); a cut-off child's the
// gap its neighbours leave in the node's range. Version 2 records hold them.
void fillVersion1ChildFaces(FchNode& node, uint64_t nodeCount,
                            const std::function<std::pair<uint32_t, uint32_t>(uint32_t)>& rangeOf);
// The whole file in memory from a reader: its nodes in one pass, then its geometry frame by frame.
ClusterFile readClusterFile(ClusterFileReader& reader, bool geometry = true);

// Keeps the first `nodes` nodes (1 <= nodes; more than the file has keeps all): whole node frames
// and the geometry are copied, only the last partial node frame is recompressed.
struct TruncateResult {
  uint64_t nodes = 0;  // nodes kept
  uint64_t bytes = 0;  // the truncated file's size
};
// Writes the first `nodes` nodes of `in` to `out`.
TruncateResult truncateClusterFile(ClusterFileReader& in, const std::filesystem::path& out, uint64_t nodes);
// The largest prefix whose whole output file (geometry included) fits in `maxBytes`; throws
// std::invalid_argument when not even one node fits.
TruncateResult truncateClusterFileToBytes(ClusterFileReader& in, const std::filesystem::path& out,
                                          uint64_t maxBytes);
// The same from a path, read under the cap the file was built under.
TruncateResult truncateClusterFile(const std::filesystem::path& in, const std::filesystem::path& out,
                                   uint64_t nodes);
TruncateResult truncateClusterFileToBytes(const std::filesystem::path& in, const std::filesystem::path& out,
                                          uint64_t maxBytes);
// The same in memory: keeps the first `nodes` nodes and marks kFchTruncated.
void truncateInMemory(ClusterFile& file, uint64_t nodes);

// Checks every invariant of docs/FORMAT.md "Semantics" (ranges, parents, boxes, areas, side
// areas); `message` names the first violation: "node N: CHECK: detail".
struct VerifyResult {
  bool ok = true;             // every invariant holds
  std::string message;        // the first invariant broken, where and how; empty when ok
  uint64_t nodesChecked = 0;  // nodes whose invariants were checked
};
// Which invariants verifyClusterFile checks besides the tree and the face ranges.
struct VerifyOptions {
  bool boxes = true;       // containment + tightness
  bool statistics = true;  // area, S, side areas
};
// Checks the file against every invariant; the first violation in `message`.
VerifyResult verifyClusterFile(const ClusterFile& file, const VerifyOptions& options = {});
// The same checks with the same verdicts over a file read under the reader's cap (version 2; a
// version 1 file, whose records place their children only through the children's own records, is
// read whole): the nodes in one pass, then the faces in one pass in face order with the nodes open
// over each face (its ancestors), the nodes waiting for their first face bucketed by it in a
// temporary file.
VerifyResult verifyClusterFile(ClusterFileReader& reader, const VerifyOptions& options = {});
// The geometry against the mesh it was built from: same triangles (by corner positions, corner
// order kept) under the same original face ids. `meshOriginalFace` empty means the identity.
VerifyResult verifyAgainstMesh(const ClusterFile& file, const MeshView& mesh,
                               std::span<const uint64_t> meshOriginalFace);
// A triangle of the mesh a file was built from: its original face id, its position among the
// mesh's triangles (as loadMesh keeps them), its corners.
struct MeshTriangle {
  uint64_t id = 0, position = 0;
  glm::vec3 corner[3];
};
// The mesh's triangles: source(visit) calls visit(batch) until every triangle went by, in any order.
using MeshTriangleSource = std::function<void(const std::function<void(std::span<const MeshTriangle>)>&)>;
// verifyAgainstMesh's checks and verdicts over a file read under the reader's cap: both sides
// bucketed by original id (in a temporary file past an eighth of the cap), then compared window by
// window in the order of the whole sort.
VerifyResult verifyAgainstMesh(ClusterFileReader& reader, const MeshTriangleSource& mesh);

// Cuts for pictures: one cluster id per triangle of file.indices (hierarchy order), the cluster of
// a face being the deepest kept node containing it, ids numbered 0, 1, ... along the face order.
// Cluster id per face (hierarchy order) for a cut through the tree: the clusters are the
// children of the kept nodes that are not kept themselves, each a contiguous run numbered
// 0, 1, ... along the face order. clusterCut keeps the shortest prefix of nodes in file order
// giving at least `clusters` clusters (all of them if there are fewer); clusterDepthCut keeps the
// nodes above `depth` (depth 0: the root alone is the one cluster).
std::vector<uint32_t> clusterCut(const ClusterFile& file, uint64_t clusters);
// The cut of the nodes above `depth`, numbered as clusterCut numbers them.
std::vector<uint32_t> clusterDepthCut(const ClusterFile& file, uint32_t depth);

// How well a cut approximates the surface (Willmott 2000, eq. 84): for the clusters of
// clusterCut(file, clusters), the sum of their eFit (surfaceFitError with the default flat
// threshold, whatever the file was built with, so files built differently compare on one measure)
// and of area * eFit (the area integral of the squared distance to each cluster's plane along its
// normal), from surfaceStats of each cluster's triangles about the centre of the vertices' bounding box;
// and the sums of box areas that measure how spatially coherent the cut is.
// Lower is better; a cut of single triangles gives 0. Needs the geometry (readClusterFile with
// geometry; else std::invalid_argument). Cost O(triangles + vertices), memory O(vertices).
struct CutFit {
  uint64_t clusters = 0;  // of the cut: at least the number asked for, or every face if there are fewer
  double sumFit = 0;      // sum of eFit (length^2)
  double sumAreaFit = 0;  // sum of area * eFit (length^4)
  // Spatial coherence: the sum of the surface areas of the cut's boxes (a node's stored oriented box; a
  // single face's or a truncation gap's axis-aligned box), and of the axis-aligned boxes of as many runs
  // of equal face count along the Morton order of the face centroids (length^2 both).
  double sumBoxArea = 0, mortonBoxArea = 0;
  // Balance: the cut's clusters holding less than 1% of the average cluster's area.
  uint64_t smallClusters = 0;
};
// The fit of the cut of `clusters` clusters.
CutFit cutFit(const ClusterFile& file, uint64_t clusters);
// The fits of several cuts, one per entry of `clusters` (the faces' Morton order sorted once for all);
// none asked, none given, geometry or not.
std::vector<CutFit> cutFits(const ClusterFile& file, std::span<const uint64_t> clusters);
// The same figures from a file read under the reader's cap: passes over the nodes (one per cut, one
// for the boxes) and over the faces (the centroids' box, then the fits), and the faces' Morton order
// sorted in runs of a temporary file past an eighth of the cap. With `branching`, the boxes' pass
// covers every node and gives branchingStats(reader) too, which saves a pass of its own.
std::vector<CutFit> cutFits(ClusterFileReader& reader, std::span<const uint64_t> clusters,
                            BranchingStats* branching = nullptr);

// The reordered mesh (faces in hierarchy order, vertices by first use — as in the .fch) as binary
// PLY (".ply") or Draco (".drc", sequential connectivity so face order and point ids are kept).
struct MeshOutOptions {
  int dracoPositionBits = 0;  // 0 = lossless float positions; else quantization bits (1 ... 30)
  int dracoSpeed = 5;         // encoder speed 0 (best) ... 10 (fastest)
};
// The reordered mesh of a hierarchy just built, or of a cluster file read back.
void writeReorderedMesh(const MeshView& mesh, const Hierarchy& hierarchy, const std::filesystem::path& path,
                        const MeshOutOptions& options = {});
void writeReorderedMesh(const ClusterFile& file, const std::filesystem::path& path,
                        const MeshOutOptions& options = {});
// An indexed mesh as it is (binary PLY or Draco, by the name's extension, as above).
void writeMesh(std::span<const glm::vec3> vertices, std::span<const uint32_t> indices,
               const std::filesystem::path& path, const MeshOutOptions& options = {});

// --- Recasting to a larger branching factor (Willmott 2000, sec. 5.5.1) ---------------------

// The b-ary tree over a binary Hierarchy: node j of the result is binary node binaryNode[j]
// (same face range, box and statistics); its children are the leaves of a subtree of the
// binary hierarchy rooted there, as node refs in the new numbering or kFaceChild | position.
struct RecastTree {
  std::vector<uint32_t> binaryNode;                        // ascending: creation order descending
  std::vector<std::array<uint32_t, kMaxBranching>> child;  // parallel to binaryNode
  std::vector<uint8_t> childCount;                         // parallel to binaryNode
  std::vector<uint8_t> joinFlag;  // some collapsed binary merge joined disjoint surfaces
};

// Rule: start from the two children of the kept binary node and repeatedly expand the frontier
// node of largest area (ties: the later-created one, i.e. the smaller index) until b children or
// only faces remain. Expanding the largest region first keeps the children of a b-ary node
// similar in size, which is what a balanced b-ary tree asks for. Throws std::invalid_argument
// for references out of range or children stored before their parent.
// RecastRule::FewestNodes instead partitions the binary internal nodes into the fewest
// connected groups of at most b - 1 (a group of c binary nodes has c + 1 leaves): Kundu and
// Misra's bottom-up greedy, optimal for this partition problem, cuts off the heaviest child
// group while a node's group is too large.
RecastTree recastHierarchy(const Hierarchy& hierarchy, unsigned branching,
                           RecastRule rule = RecastRule::LargestArea);

// --- Outputs: mesh writers and the files every output is written through ---------------------

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

// An output file that appears under its final name only when complete: data goes to a
// temporary name beside the target and is renamed on commit(); destroyed uncommitted, the
// temporary file is removed. Writes are buffered; every failure throws Error (Output) naming the file.
//
// A stream is written in place instead: standard output ("-"), and a target that exists and is
// not a regular file (a named pipe, a device, a socket). Renaming a temporary over a pipe would
// replace it with a regular file while its reader waits forever; a stream takes bytes in order
// only, so writeAt() is refused, and a failed write fails the run as on standard output.
class OutputFile {
 public:
  // "-" writes to standard output (no temporary, nothing to remove).
  explicit OutputFile(const std::filesystem::path& path);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  void write(const void* data, size_t bytes);
  void write(std::string_view text) { write(text.data(), text.size()); }
  // Overwrites bytes already written (a header whose contents are known last); the next write
  // appends at the end again. Not for streams (std::logic_error).
  void writeAt(uint64_t offset, std::string_view bytes);
  uint64_t bytesWritten() const { return written_; }
  bool isStream() const { return stream_; }
  // Flushes, syncs and renames to the final name (a stream: flushes and closes).
  void commit();
  const std::filesystem::path& path() const { return path_; }

 private:
  [[noreturn]] void fail(const char* what) const;
  void startWriteback();  // hands the bytes written since the last call to the disk
  std::filesystem::path path_;
  std::filesystem::path temporary_;
  struct Closer {
    void operator()(std::FILE* f) const;
  };
  std::unique_ptr<std::FILE, Closer> file_;
  bool stream_ = false;
  bool committed_ = false;
  uint64_t written_ = 0;
  uint64_t handedToDisk_ = 0;  // bytes whose writeback has been started
};

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

// Streaming binary STL writer (each triangle its three corners' positions, a zero normal), by the
// rules of PlyWriter: the count given up front, a temporary name renamed on finish().
class StlWriter {
 public:
  StlWriter(const std::filesystem::path& path, uint64_t triangleCount);
  ~StlWriter();
  StlWriter(const StlWriter&) = delete;
  StlWriter& operator=(const StlWriter&) = delete;
  void addTriangle(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);
  void finish();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// A cut's clusters as NumPy arrays in an uncompressed .npz (numpy.load), written atomically: node
// (int64, -1 for a single face or a truncation gap), first and triangles (uint64), cost, area and
// perimeter (float32), center and half_extents (n x 3 float32), orientation (n x 4 float32: x, y, z,
// w); the float arrays NaN where there is no node. records[i]: the node of cut[i] where it has one.
void writeCutNpz(const std::filesystem::path& path, std::span<const CutCluster> cut,
                 std::span<const FchNode> records);

// A JSON object written field by field, for reports (`--json` of the command line, the Python
// package's report): nested objects by beginObject / endObject, numbers as C's %.9g, non-finite
// ones as null, two-space indents.
class JsonWriter {
 public:
  JsonWriter();
  void key(const std::string& name);
  void field(const std::string& name, const std::string& value);
  void field(const std::string& name, const char* value);
  void field(const std::string& name, bool value);
  void field(const std::string& name, uint64_t value);
  void field(const std::string& name, int64_t value);
  void field(const std::string& name, uint32_t value);
  void field(const std::string& name, int value);
  void field(const std::string& name, double value);
  void field(const std::string& name, const std::vector<double>& values);
  void beginObject(const std::string& name);
  void endObject();
  // The text, every object still open closed, with a final newline.
  std::string finish();

 private:
  void open();
  void separator();
  std::string out_;
  int depth_ = 0;
  bool first_ = true;
};

}  // namespace facetree
