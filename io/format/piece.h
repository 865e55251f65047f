// Internal to io/: a piece of a cluster file (WriteOptions::piece) and the layout every writer of
// a file starts from.
//
// A piece file is its frames, section by section in file order (nodes, vertices, triangles, ids),
// then a trailer: its PieceRange, its vertices' bounds, the root's decoded box when it holds the
// root of a compact-box file, its frames' index entries (offsets within the piece), the trailer's
// size, an XXH64 of the trailer and a magic. The pieces of one file come from one build on one
// kind of machine: the trailer is host-order bytes, as the build's own manifests are.
#pragma once

#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/io.h"

namespace facetree::fch {

// The header and framing a writer of `info` with `options` makes (bounds empty, no frames).
FchLayout startLayout(const StreamFileInfo& info, const WriteOptions& options);

struct PieceTrailer {
  PieceRange range;
  glm::vec3 boundsMin{0.0f}, boundsMax{0.0f};  // of its vertices (min > max: none)
  bool hasRoot = false;                        // compact boxes: it holds the root, whose box is rootBox
  NodeBox rootBox{};
  std::vector<FchFrame> frames;  // offsets within the piece
};
// The trailer's bytes, to append after the frames.
std::string encodePieceTrailer(const PieceTrailer& trailer);

}  // namespace facetree::fch
