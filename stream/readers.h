// Internal: the per-format reader factories used by openMesh after format detection, and
// the descriptor entry point used by openStandardInput and the tests.
#pragma once

#include <memory>
#include <string>

#include "byte_source.h"
#include "facetree/stream.h"
#include "format_detect.h"

namespace facetree::stream_detail {

// `info` carries the name, the detected format and whether the input was zstd-compressed;
// `input` is positioned at the start of the (decompressed) mesh file.
std::unique_ptr<TriangleReader> makePlyReader(std::unique_ptr<InputBuffer> input, MeshInfo info);
std::unique_ptr<TriangleReader> makeObjReader(std::unique_ptr<InputBuffer> input, MeshInfo info);
std::unique_ptr<TriangleReader> makeStlReader(std::unique_ptr<InputBuffer> input, MeshInfo info);
std::unique_ptr<TriangleReader> makeDracoReader(std::unique_ptr<InputBuffer> input, MeshInfo info,
                                                uint64_t wholeMeshLimitBytes = 0);

// The reader for an already detected mesh format; nullptr for Empty, Unknown and Zstd.
// `wholeMeshLimitBytes`: ReadOptions::wholeMeshLimitBytes.
std::unique_ptr<TriangleReader> makeReader(DetectedFormat format, std::unique_ptr<InputBuffer> input,
                                           MeshInfo info, uint64_t wholeMeshLimitBytes = 0);

// Detects the format of `input` (unwrapping zstd) and opens the matching reader.
std::unique_ptr<TriangleReader> openInput(std::unique_ptr<InputBuffer> input, const std::string& name,
                                          const ReadOptions& options);

// Reads a mesh from an open descriptor without seeking and without using its size (like a
// pipe); the descriptor is not closed. `name` is used in messages. For tests and stdin.
std::unique_ptr<TriangleReader> openFileDescriptor(int fd, const std::string& name,
                                                   const ReadOptions& options = {});

}  // namespace facetree::stream_detail
