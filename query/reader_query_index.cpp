// ReaderQueryIndex (facetree/query.h): a reader's nodes laid out in pages for queries
// (node_pages.h), kept for the queries that follow.
#include "facetree/query.h"
#include "query_source.h"

namespace facetree {

ReaderQueryIndex::ReaderQueryIndex(ClusterFileReader& reader) : state_(std::make_unique<State>(reader)) {}
ReaderQueryIndex::~ReaderQueryIndex() = default;
ClusterFileReader& ReaderQueryIndex::reader() const {
  return state_->reader;
}
uint64_t ReaderQueryIndex::temporaryBytes() const {
  return state_->pages.temporaryBytes();
}
uint64_t ReaderQueryIndex::peakPageBytes() const {
  return state_->pages.peakBytes();
}

}  // namespace facetree
