// ReaderQueryIndex (facetree/query.h): a reader's nodes laid out in pages for queries
// (node_pages.h), kept for the queries that follow.
#include "facetree/error.h"
#include "facetree/query.h"
#include "query_source.h"
#include "ray_index.h"

namespace facetree {

uint64_t ReaderQueryIndex::State::wholeBytes(const FileHeader& header) {
  // A node: its record, and at most two lanes of packets (a packet of four lanes holds at least
  // two members but the root's); a triangle: its indices, original id, corners and a range.
  return header.nodeCount * (sizeof(FchNode) + 2 * sizeof(query::RayPacket) / 4) +
         header.triangleCount *
             (3 * sizeof(uint32_t) + sizeof(uint64_t) + 3 * sizeof(glm::vec3) + sizeof(query::FaceRange)) +
         header.vertexCount * sizeof(glm::vec3);
}

ReaderQueryIndex::State::State(ClusterFileReader& r) : reader(r) {
  if (wholeBytes(r.header()) <= r.memoryBytes() / 2) {
    file = std::make_unique<ClusterFile>(readClusterFile(r));
    const uint64_t faces = file->indices.size() / 3;
    for (size_t i = 0; i < file->nodes.size(); ++i)  // a damaged file's range past the triangles
      if (uint64_t{file->nodes[i].first} + file->nodes[i].count > faces)
        throw Error(ErrorCategory::Input, r.name() + ": node " + std::to_string(i) + ": faces " +
                                              std::to_string(file->nodes[i].first) + " + " +
                                              std::to_string(file->nodes[i].count) + " past the triangles");
    layout = std::make_unique<RayLayout>(*file);  // its ranges lie in the nodes' checked above
  } else {
    pages = std::make_unique<query::NodePages>(r, r.memoryBytes() / 4);
    rays = std::make_unique<query::RayPages>(*pages);
  }
}

ReaderQueryIndex::ReaderQueryIndex(ClusterFileReader& reader) : state_(std::make_unique<State>(reader)) {}
ReaderQueryIndex::~ReaderQueryIndex() = default;
ClusterFileReader& ReaderQueryIndex::reader() const {
  return state_->reader;
}
uint64_t ReaderQueryIndex::temporaryBytes() const {
  return state_->pages ? state_->pages->temporaryBytes() : 0;
}
uint64_t ReaderQueryIndex::peakPageBytes() const {
  return state_->pages ? state_->pages->peakBytes() : 0;
}

}  // namespace facetree
