// Buffered fixed-size record streams over one compressed SpillFile (see bucket_spill.h).
#include "grid/bucket_spill.h"

#include <zstd.h>

#include <algorithm>
#include <stdexcept>

namespace facetree {

BucketSpill::BucketSpill(TempSpace& space, std::string_view stem, size_t buckets, size_t recordBytes,
                         size_t bufferBytes, int level, bool discardable)
    : file_(space, stem, discardable),
      writer_(level),
      recordBytes_(recordBytes),
      bufferBytes_(
          std::max<size_t>(1, std::min(bufferBytes, kMaxSpillBlockBytes) / std::max<size_t>(1, recordBytes)) *
          recordBytes),
      // Uninitialised: the pages of a bucket become resident only once records land in it.
      buffer_(std::make_unique_for_overwrite<std::byte[]>(buckets * bufferBytes_)),
      fill_(buckets, 0),
      records_(buckets, 0),
      head_(buckets, kNoBlock),
      tail_(buckets, kNoBlock) {
  if (recordBytes == 0 || recordBytes > kMaxSpillBlockBytes)
    throw std::invalid_argument("BucketSpill: record size must be 1 byte to 256 MiB");
}

uint64_t BucketSpill::memoryBound(size_t buckets, size_t recordBytes, size_t bufferBytes) {
  const uint64_t buffer = std::max<size_t>(1, bufferBytes / std::max<size_t>(1, recordBytes)) * recordBytes;
  constexpr uint64_t kPerBucket = sizeof(size_t) + sizeof(uint64_t) + 2 * sizeof(uint32_t);
  // The block list grows by sizeof(ChainedBlock) per flushed block, 0.04% of the data at 64 KiB blocks.
  return buckets * (buffer + kPerBucket) + ZSTD_compressBound(buffer);
}

void BucketSpill::appendMany(size_t bucket, const void* records, size_t n) {
  const std::byte* from = static_cast<const std::byte*>(records);
  size_t bytes = n * recordBytes_;
  std::byte* buffer = buffer_.get() + bucket * bufferBytes_;
  records_[bucket] += n;
  while (bytes > 0) {
    const size_t take = std::min(bytes, bufferBytes_ - fill_[bucket]);
    std::memcpy(buffer + fill_[bucket], from, take);
    fill_[bucket] += take;
    from += take;
    bytes -= take;
    if (fill_[bucket] == bufferBytes_) flush(bucket);
  }
}

void BucketSpill::flush(size_t bucket) {
  if (fill_[bucket] == 0) return;
  const SpillBlock block = file_.append({buffer_.get() + bucket * bufferBytes_, fill_[bucket]}, writer_);
  if (blocks_.size() >= kNoBlock) throw std::length_error("BucketSpill: more than 2^32 blocks");
  const uint32_t index = static_cast<uint32_t>(blocks_.size());
  blocks_.push_back({block, kNoBlock});
  if (tail_[bucket] == kNoBlock)
    head_[bucket] = index;
  else
    blocks_[tail_[bucket]].next = index;
  tail_[bucket] = index;
  fill_[bucket] = 0;
}

void BucketSpill::flushAll() {
  for (size_t bucket = 0; bucket < buckets(); ++bucket) flush(bucket);
}

void BucketSpill::readBucket(size_t bucket, std::vector<std::byte>& out, SpillCodec& codec) const {
  size_t at = out.size();
  out.resize(at + records_[bucket] * recordBytes_);
  // Straight into `out`: no block of scratch beyond the codec's compressed one.
  for (uint32_t b = head_[bucket]; b != kNoBlock; b = blocks_[b].next) {
    const SpillBlock& block = blocks_[b].block;
    file_.read(block, std::span<std::byte>(out.data() + at, block.rawBytes), codec);
    at += block.rawBytes;
  }
  if (fill_[bucket] > 0) std::memcpy(out.data() + at, buffer_.get() + bucket * bufferBytes_, fill_[bucket]);
}

}  // namespace facetree
