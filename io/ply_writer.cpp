#include "io/io.h"
namespace facetree {
struct PlyWriter::State {};
PlyWriter::PlyWriter(const std::filesystem::path&, uint64_t, uint64_t) {}
PlyWriter::~PlyWriter() = default;
void PlyWriter::addVertex(const glm::vec3&) {}
void PlyWriter::addTriangle(uint32_t, uint32_t, uint32_t) {}
void PlyWriter::finish() {}
}  // namespace facetree
