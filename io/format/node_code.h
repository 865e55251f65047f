// Internal to io/: version 2 node records (docs/FORMAT.md "Node frames, version 2"). A node is
// quantised into a NodeCode (quantizeNode), NodeCodes are laid out as columns of byte planes
// (encodeNodeFrame / decodeNodeFrame), and a NodeDecoder turns them back into FchNodes in file
// order, deriving face ranges from the parents. Truncation re-encodes NodeCodes as they were read,
// so kept records never change.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "facetree/io.h"
#include "format/node_frontier.h"

namespace facetree::fch {

// S and the side-area sums are stored as fractions of the node's area in this many bits.
inline constexpr unsigned kFractionBits = 12;
// Exact boxes: half extents are whole multiples of 2^(scale - kHalfExtentBits), scale the
// exponent of the largest half extent (2^scale >= it), rounded up: at most 2^-17 of it looser.
inline constexpr int kHalfExtentBits = 18;
// The scale's stored byte is scale + kScaleBias; scales run from kMinScale to kMaxScale.
inline constexpr int kScaleBias = 120, kMinScale = -106, kMaxScale = 128;
// Compact boxes: each box face on a grid of 255 steps across the parent box's extent along the
// child's axis, widened on either side by kCompactMargin of the parent's half extents' sum and
// kCompactCoordinateMargin of its centre's coordinates (float centres round by 2^-24 of them).
inline constexpr double kCompactMargin = 0x1p-16, kCompactCoordinateMargin = 0x1p-20;

// One node as version 2 stores it.
struct NodeCode {
  uint8_t shape = 0;     // childCount - 2 | flags << 3 | orientation.largest << 5
  uint8_t faceMask = 0;  // bit c: child c is a single face
  uint8_t derived = 0;   // the child slot whose face count follows from the others'
  float cost = 0, area = 0, perimeter = 0;
  uint16_t sumNormal[3] = {};          // zigzag of round(S / area * (2^(kFractionBits-1) - 1))
  uint16_t sideSum[3] = {};            // round((side+ + side-) / area * (2^kFractionBits - 1)) per axis
  uint16_t orientation[3] = {};        // zigzag of OrientationCode::component
  uint8_t scale = 0;                   // exact boxes
  float center[3] = {};                // exact boxes
  uint32_t half[3] = {};               // exact boxes: half extents in units of 2^(scale - kHalfExtentBits)
  uint8_t lo[3] = {}, hi[3] = {};      // compact boxes (0 for the root, whose box is in the header)
  uint32_t ref[kMaxBranching] = {};    // node children in slot order: child index - own index
  uint32_t faces[kMaxBranching] = {};  // face counts of the node children but `derived`, in slot order
  uint8_t refCount = 0, faceCountCount = 0;
};

// The compact box of a child from its parent's (as decoded) and its codes: the reader's and the
// writer's one definition. Side areas are left as they are.
void compactBox(const NodeBox& parent, const glm::quat& orientation, const uint8_t lo[3], const uint8_t hi[3],
                NodeBox& box);
// The face of the compact box along each axis lies within this of the exact box's (verify's bound).
void compactStep(const NodeBox& parent, const glm::quat& orientation, double step[3]);

// Quantises `node` (file index `index`; children with their face counts in childFaces). `parent`:
// the parent's box as decoded (compact boxes; null for the root). `decoded` gets the node's box as
// a reader will decode it (compact boxes; the root's is its own). Throws std::invalid_argument
// for what the format cannot hold: an orientation off the lattice, face counts that do not add
// up, non-finite values.
NodeCode quantizeNode(const FchNode& node, uint64_t index, BoxPrecision precision, const NodeBox* parent,
                      NodeBox* decoded);

// Columns of a frame of codes, and back: decodeNodeFrame appends the frame's `n` codes to `out`
// (`structure`: their S, side areas, orientations and boxes left zero)
// and returns an empty string, or why the payload is invalid (its size is checked against the
// child counts before anything is read).
std::string encodeNodeFrame(std::span<const NodeCode> codes, BoxPrecision precision);
void encodeNodeFrame(std::span<const NodeCode> codes, BoxPrecision precision,
                     std::string& out);  // into `out`
std::string decodeNodeFrame(std::string_view raw, size_t n, BoxPrecision precision, unsigned branching,
                            std::vector<NodeCode>& out, bool structure = false);
// The records of version 2 node frame `i` of `file` (payload `raw`) as stored, appended to `out`
// (truncation re-encodes them unchanged); a payload decodeNodeFrame refuses fails the file there.
class SourceFile;
void decodeNodeCodes(const SourceFile& file, size_t i, const std::string& raw, std::vector<NodeCode>& out,
                     bool structure = false);

// A spilled node run's record (encodeNodeRun): quantizeNode's fields with the orientation on
// `precision`'s lattice and the box always as exact boxes store it, whatever `precision` is.
NodeCode quantizeRunNode(const FchNode& node, uint64_t index, BoxPrecision precision);
// A run's record (quantizeRunNode) as a file of compact boxes holds it at `index`: its box, stored
// as exact boxes store it, quantised against `parent`'s decoded box (null for the root, whose box
// goes in the header); `decoded` gets the box a reader decodes. Returns an empty string, or why the
// record is invalid or its box does not fit its parent's.
std::string compactRunRecord(NodeCode& code, uint64_t index, const NodeBox* parent, NodeBox& decoded);
// The compact box of `box` on its parent's grid, into code.lo and code.hi (rounded outwards, widened
// by a step where the decoded box would not hold it); returns the box as a reader decodes it. Throws
// std::logic_error when the box does not fit its parent's.
NodeBox quantizeCompactBox(const NodeBox& box, const NodeBox& parent, uint64_t index, NodeCode& code);

// Decodes node `index` on its own from its code and what its parent's record gives it (`range`: face
// range; `parentBox`: the parent's decoded box, needed by compact boxes but the root's), as
// NodeDecoder does in file order. `structure`: S and the box left zero. Returns an empty string, or
// why the record is invalid.
std::string decodeNodeAt(const FileHeader& header, const NodeBox& rootBox, const NodeCode& code,
                         uint64_t index, const PendingChild& range, const NodeBox* parentBox, bool structure,
                         FchNode& node);

// Turns codes back into nodes in file order: face ranges and depths follow from the parents'
// records (the root covers every triangle), compact boxes from the parents' boxes. What it holds
// is the cut of the children announced and not yet decoded (NodeFrontier) and, for compact boxes,
// each such child's parent box in a second frontier; the two share the budget.
class NodeDecoder {
 public:
  // `budget`, `tmp`: the announced children's share of memory, and where the rest goes (NodeFrontier).
  // `structure`: records as NodeFields::Structure gives them (S and the box left zero), so that
  // compact boxes need no parents' boxes.
  NodeDecoder(const FileHeader& header, const NodeBox& rootBox, uint32_t nodesPerFrame, uint64_t budget = 0,
              const std::filesystem::path& tmp = {}, bool structure = false);
  // Decodes node `index` (0, 1, 2, ... in turn) into `node`, and its depth (the root's is 1).
  // Returns an empty string, or why the record is invalid.
  std::string decode(const NodeCode& code, uint64_t index, FchNode& node, uint32_t& depth);
  // Bytes held for the children announced and not yet decoded, and written to the temporary file.
  uint64_t heldBytes() const;
  uint64_t spilledBytes() const;
  bool structure() const { return structure_; }
  // The ranges its parents gave each node of the frame decoded last, once all its nodes are decoded
  // (PendingChild by position in the frame; the root's is not there).
  const std::vector<PendingChild>& frameRanges() const { return *slots_; }

 private:
  bool compact() const { return header_.boxes == BoxPrecision::Compact && !structure_; }
  const FileHeader& header_;
  NodeBox rootBox_;
  uint32_t nodesPerFrame_;
  NodeFrontier<PendingChild> frontier_;
  NodeFrontier<PendingParentBox> boxes_;                     // compact boxes only
  const std::vector<PendingChild>* slots_ = nullptr;         // the current frame's announced children
  const std::vector<PendingParentBox>* boxSlots_ = nullptr;  // and their parents' boxes
  uint64_t next_ = 0, frame_ = ~uint64_t{0};
  bool structure_ = false;
};

}  // namespace facetree::fch
