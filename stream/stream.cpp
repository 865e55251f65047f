// Entry points: open a file or descriptor, detect the format (unwrapping zstd), and hand the
// buffered input to the matching reader.
#include "facetree/stream.h"

#include <unistd.h>

#include "byte_source.h"
#include "format_detect.h"
#include "read_error.h"
#include "readers.h"
#include "vertex_store.h"

namespace facetree {

const char* formatName(MeshFormat format) {
  switch (format) {
    case MeshFormat::PlyAscii:
      return "PLY ascii";
    case MeshFormat::PlyBinaryLittleEndian:
      return "PLY binary little endian";
    case MeshFormat::PlyBinaryBigEndian:
      return "PLY binary big endian";
    case MeshFormat::Obj:
      return "OBJ";
    case MeshFormat::StlAscii:
      return "STL ascii";
    case MeshFormat::StlBinary:
      return "STL binary";
    case MeshFormat::Draco:
      return "Draco";
  }
  return "unknown";
}

namespace stream_detail {

std::unique_ptr<TriangleReader> openInput(std::unique_ptr<InputBuffer> input, const std::string& name,
                                          const ReadOptions& options) {
  MeshInfo info;
  info.name = name;
  DetectedFormat format = detectFormat(*input, input->size());
  if (format == DetectedFormat::Zstd) {
    input = std::make_unique<InputBuffer>(makeZstdSource(std::move(input), name), options.bufferBytes);
    info.zstdCompressed = true;
    // The decompressed size is unknown (a frame's declared size is not trusted).
    format = detectFormat(*input, std::nullopt);
    if (format == DetectedFormat::Zstd)
      throwReadError(name, Place::byte(0), "zstd inside zstd is not supported");
  }
  if (format == DetectedFormat::Empty) throwReadError(name, Place::byte(0), "empty file");
  if (auto reader = makeReader(format, std::move(input), std::move(info), options.wholeMeshLimitBytes)) {
    const MeshFormat f = reader->info().format;
    const bool indexed = f == MeshFormat::PlyAscii || f == MeshFormat::PlyBinaryLittleEndian ||
                         f == MeshFormat::PlyBinaryBigEndian || f == MeshFormat::Obj;
    if (options.vertexSink && indexed) static_cast<ReaderBase&>(*reader).deferPositions(options.vertexSink);
    return reader;
  }
  throwReadError(name, Place::byte(0), "unknown mesh format");
}

std::unique_ptr<TriangleReader> makeReader(DetectedFormat format, std::unique_ptr<InputBuffer> input,
                                           MeshInfo info, uint64_t wholeMeshLimitBytes) {
  switch (format) {
    case DetectedFormat::Empty:
    case DetectedFormat::Unknown:
    case DetectedFormat::Zstd:
      return nullptr;
    case DetectedFormat::Ply:
      return makePlyReader(std::move(input), std::move(info));
    case DetectedFormat::Draco:
      return makeDracoReader(std::move(input), std::move(info), wholeMeshLimitBytes);
    case DetectedFormat::Obj:
      return makeObjReader(std::move(input), std::move(info));
    case DetectedFormat::StlAscii:
      info.format = MeshFormat::StlAscii;
      return makeStlReader(std::move(input), std::move(info));
    case DetectedFormat::StlBinary:
      info.format = MeshFormat::StlBinary;
      return makeStlReader(std::move(input), std::move(info));
  }
  return nullptr;
}

std::unique_ptr<TriangleReader> openFileDescriptor(int fd, const std::string& name,
                                                   const ReadOptions& options) {
  auto source = std::make_unique<FdSource>(fd, name, false);
  return openInput(std::make_unique<InputBuffer>(std::move(source), options.bufferBytes), name, options);
}

}  // namespace stream_detail

std::unique_ptr<TriangleReader> openMesh(const std::filesystem::path& path, const ReadOptions& options) {
  const std::string name = path.string();
  auto source = stream_detail::FdSource::open(name, name);
  return stream_detail::openInput(
      std::make_unique<stream_detail::InputBuffer>(std::move(source), options.bufferBytes), name, options);
}

std::unique_ptr<TriangleReader> openStandardInput(const ReadOptions& options) {
  return stream_detail::openFileDescriptor(STDIN_FILENO, "-", options);
}

}  // namespace facetree
