// Buffered fixed-size record streams over one compressed SpillFile (facetree/storage.h).
#include "facetree/storage.h"

#include <zstd.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace facetree {

class BucketSpill::Writer {
 public:
  static constexpr size_t kSpares = 2;  // buffers in flight: one being written, one waiting
  struct Block {
    std::unique_ptr<std::byte[]> bytes;
    size_t size = 0;
    SpillBlock* target = nullptr;
  };
  HelperRing<Block> behind;

  Writer(SpillFile& file, int level)
      : behind(
            [&file, codec = SpillCodec(level)](Block& b, unsigned) mutable {
              *b.target = file.append({b.bytes.get(), b.size}, codec);
            },
            kSpares) {}
};

BucketSpill::BucketSpill(TempSpace& space, std::string_view stem, size_t buckets, size_t recordBytes,
                         size_t bufferBytes, int level, bool discardable, bool background)
    : BucketSpill(std::make_unique<SpillFile>(space, stem, discardable), buckets, recordBytes, bufferBytes,
                  level, background) {}

BucketSpill::BucketSpill(TempSpace& space, SpillFile::Named name, size_t buckets, size_t recordBytes,
                         size_t bufferBytes, int level, bool background)
    : BucketSpill(std::make_unique<SpillFile>(space, std::move(name)), buckets, recordBytes, bufferBytes,
                  level, background) {}

BucketSpill::BucketSpill(std::unique_ptr<SpillFile> file, size_t buckets, size_t recordBytes,
                         size_t bufferBytes, int level, bool background)
    : file_(std::move(file)),
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
  if (background) background_ = std::make_unique<Writer>(*file_, level);
}

BucketSpill::~BucketSpill() = default;

uint64_t BucketSpill::backgroundBytes(size_t bufferBytes) {
  // The spare buffers, and the helper's codec: its contexts and one compressed block of scratch.
  return Writer::kSpares * bufferBytes + ZSTD_compressBound(bufferBytes) + (uint64_t{512} << 10);
}

void BucketSpill::settle() const {
  if (background_) background_->behind.settle();
}

void BucketSpill::releaseBuffers() {
  flushAll();
  background_.reset();
  buffer_.reset();
}

void BucketSpill::commit() {
  releaseBuffers();
  file_->commit();
}

namespace {

// The index: buckets and record size, then per bucket its record count and block count, then
// every block (offset, compressed and raw bytes), all little-endian as the machine writes them.
template <class T>
void put(std::string& out, const T& value) {
  out.append(reinterpret_cast<const char*>(&value), sizeof value);
}
template <class T>
bool take(std::string_view& in, T& value) {
  if (in.size() < sizeof value) return false;
  std::memcpy(&value, in.data(), sizeof value);
  in.remove_prefix(sizeof value);
  return true;
}

}  // namespace

std::string BucketSpill::index() const {
  if (buffer_ || lists_)
    throw std::logic_error(
        "BucketSpill::index: buffers still open (commit or releaseBuffers first), or "
        "the blocks offloaded");
  std::string out;
  put(out, uint64_t{buckets()});
  put(out, uint64_t{recordBytes_});
  for (size_t bucket = 0; bucket < buckets(); ++bucket) {
    uint32_t count = 0;
    for (uint32_t b = head_[bucket]; b != kNoBlock; b = blocks_[b].next) ++count;
    put(out, records_[bucket]);
    put(out, count);
  }
  for (size_t bucket = 0; bucket < buckets(); ++bucket)
    for (uint32_t b = head_[bucket]; b != kNoBlock; b = blocks_[b].next) {
      const SpillBlock& block = blocks_[b].block;
      put(out, block.offset);
      put(out, block.compressedBytes);
      put(out, block.rawBytes);
    }
  return out;
}

std::unique_ptr<BucketSpill> BucketSpill::open(TempSpace& space, const std::filesystem::path& path,
                                               std::string_view index) {
  std::vector<uint32_t> records;
  return openSegments(
      space, std::span(&path, 1), [&](size_t) { return std::string(index); }, 0, SIZE_MAX, records);
}

std::unique_ptr<BucketSpill> BucketSpill::openSegments(TempSpace& space,
                                                       std::span<const std::filesystem::path> paths,
                                                       const std::function<std::string(size_t)>& indexOf,
                                                       size_t first, size_t end,
                                                       std::vector<uint32_t>& records) {
  SegmentReader reader(space, paths, first, end);
  for (size_t s = 0; s < paths.size(); ++s) reader.add(indexOf(s));
  return reader.finish(records);
}

BucketSpill::SegmentReader::SegmentReader(TempSpace& space, std::span<const std::filesystem::path> paths,
                                          size_t first, size_t end, bool owned)
    : paths_(paths.begin(), paths.end()), first_(first), end_(end), owned_(owned) {
  if (paths.empty()) throw std::invalid_argument("BucketSpill::SegmentReader: no segments");
  file_ = SpillFile::open(space, paths);
  if (owned_) file_->ownOpened();
}

BucketSpill::SegmentReader::~SegmentReader() = default;

void BucketSpill::SegmentReader::add(std::string_view index) {
  const size_t s = added_;
  if (s >= paths_.size()) throw std::logic_error("BucketSpill::SegmentReader: more indexes than segments");
  const auto bad = [&](const std::string& why) {
    throw Error(ErrorCategory::Input, paths_[s].string() + ": bucket index " + why);
  };
  uint64_t buckets = 0, recordBytes = 0;
  if (!take(index, buckets) || !take(index, recordBytes)) bad("cut short");
  if (recordBytes == 0 || recordBytes > kMaxSpillBlockBytes || buckets > index.size() / 12)
    bad("with " + std::to_string(buckets) + " buckets of " + std::to_string(recordBytes) + "-byte records");
  if (!spill_) {
    spill_.reset(new BucketSpill(std::move(file_), buckets, recordBytes, recordBytes, 0, false));
    spill_->buffer_.reset();
    records_.assign(paths_.size() * buckets, 0);
    counts_.assign(buckets, 0);
  } else if (buckets != spill_->buckets() || recordBytes != spill_->recordBytes_) {
    bad("of other buckets than the segments before it");
  }
  BucketSpill& spill = *spill_;
  for (size_t bucket = 0; bucket < buckets; ++bucket) {
    uint64_t n = 0;
    if (!take(index, n) || !take(index, counts_[bucket])) bad("cut short");
    if (n > UINT32_MAX) bad("of a bucket of " + std::to_string(n) + " records");
    records_[s * buckets + bucket] = static_cast<uint32_t>(n);
    spill.records_[bucket] += n;
  }
  // The blocks are bucket by bucket, each kBlockEntry bytes: a reader of a few buckets of many
  // segments reads only theirs. Every bucket's blocks are checked by the reader that keeps them.
  constexpr size_t kBlockEntry = sizeof(uint64_t) + 2 * sizeof(uint32_t);
  uint64_t before = 0, blocks = 0;
  for (size_t bucket = 0; bucket < buckets; ++bucket) {
    if (bucket < first_) before += counts_[bucket];
    blocks += counts_[bucket];
  }
  if (index.size() != blocks * kBlockEntry)
    bad(index.size() < blocks * kBlockEntry ? "cut short" : "with bytes past its end");
  index.remove_prefix(before * kBlockEntry);
  for (size_t bucket = first_; bucket < std::min<size_t>(end_, buckets); ++bucket) {
    uint64_t bytes = 0;
    for (uint32_t k = 0; k < counts_[bucket]; ++k) {
      SpillBlock block;
      take(index, block.offset), take(index, block.compressedBytes), take(index, block.rawBytes);
      if (block.rawBytes % recordBytes != 0 || block.offset >> SpillFile::kSegmentShift != 0)
        bad("with a block of part of a record or of another segment");
      bytes += block.rawBytes;
      block.offset |= uint64_t{s} << SpillFile::kSegmentShift;  // this segment in the files opened together
      spill.blocks_[spill.reserveBlock(bucket)].block = block;
      if (owned_) spill.file_->countBlock(block);
    }
    if (bytes != uint64_t{records_[s * buckets + bucket]} * recordBytes)
      bad("of bucket " + std::to_string(bucket) + ": its blocks do not hold its records");
  }
  ++added_;
}

std::unique_ptr<BucketSpill> BucketSpill::SegmentReader::finish(std::vector<uint32_t>& records) {
  if (added_ != paths_.size())
    throw std::logic_error("BucketSpill::SegmentReader: a segment without its index");
  records = std::move(records_);
  return std::move(spill_);
}

uint32_t BucketSpill::reserveBlock(size_t bucket) {
  if (blocks_.size() >= kNoBlock) throw std::length_error("BucketSpill: more than 2^32 blocks");
  const uint32_t index = static_cast<uint32_t>(blocks_.size());
  blocks_.push_back({SpillBlock{}, kNoBlock});
  if (tail_[bucket] == kNoBlock)
    head_[bucket] = index;
  else
    blocks_[tail_[bucket]].next = index;
  tail_[bucket] = index;
  return index;
}

uint64_t BucketSpill::memoryBound(size_t buckets, size_t recordBytes, size_t bufferBytes) {
  const uint64_t buffer = std::max<size_t>(1, bufferBytes / std::max<size_t>(1, recordBytes)) * recordBytes;
  constexpr uint64_t kPerBucket = sizeof(size_t) + sizeof(uint64_t) + 2 * sizeof(uint32_t);
  // The block list grows by sizeof(ChainedBlock) per flushed block, 0.04% of the data at 64 KiB
  // blocks, unless offloaded as it grows (offloadBlocks with entries).
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
  if (offloadAt_ && blocks_.size() >= offloadAt_) offloadRound();
  const std::span<const std::byte> bytes(buffer_.get() + bucket * bufferBytes_, fill_[bucket]);
  if (background_) {
    Writer::Block& b = background_->behind.slot();
    if (!b.bytes) b.bytes = std::make_unique_for_overwrite<std::byte[]>(bufferBytes_);
    std::memcpy(b.bytes.get(), bytes.data(), bytes.size());
    b.size = bytes.size();
    b.target = &blocks_[reserveBlock(bucket)].block;
    background_->behind.submit();
  } else {
    const SpillBlock block = file_->append(bytes, writer_);
    blocks_[reserveBlock(bucket)].block = block;
  }
  fill_[bucket] = 0;
}

void BucketSpill::flushAll() {
  for (size_t bucket = 0; bucket < buckets(); ++bucket) flush(bucket);
  settle();
}

void BucketSpill::offloadBlocks(TempSpace& space, size_t entries) {
  if (!lists_) {
    lists_ = std::make_unique<SpillFile>(space, "bucket-blocks", /*discardable=*/true, sizeof(SpillBlock));
    listOf_.assign(buckets(), SpillBlock{});
  }
  offloadAt_ = entries;
  offloadRound();
}

void BucketSpill::offloadRound() {
  settle();  // every block reserved has its handle
  std::vector<SpillBlock> chunk;
  for (size_t bucket = 0; bucket < buckets(); ++bucket) {
    if (head_[bucket] == kNoBlock) continue;
    chunk.assign(1, listOf_[bucket]);
    for (uint32_t b = head_[bucket]; b != kNoBlock; b = blocks_[b].next) chunk.push_back(blocks_[b].block);
    listOf_[bucket] = lists_->append(std::as_bytes(std::span(chunk)), writer_);
    head_[bucket] = tail_[bucket] = kNoBlock;
  }
  std::deque<ChainedBlock>().swap(blocks_);
}

std::vector<SpillBlock> BucketSpill::blockList(size_t bucket, SpillCodec& codec,
                                               std::vector<SpillBlock>* chunks) const {
  // Backwards from the last chunk, then in order.
  std::vector<std::vector<SpillBlock>> parts;
  std::vector<std::byte> raw;
  for (SpillBlock at = listOf_[bucket]; at.rawBytes != 0;) {
    if (chunks) chunks->push_back(at);
    lists_->read(at, raw, codec);
    if (raw.size() < sizeof(SpillBlock) || raw.size() % sizeof(SpillBlock) != 0)
      throw std::logic_error("BucketSpill: a chunk of a block list of part of a handle");
    std::vector<SpillBlock>& part = parts.emplace_back(raw.size() / sizeof(SpillBlock));
    std::memcpy(part.data(), raw.data(), raw.size());
    at = part.front();
  }
  std::vector<SpillBlock> list;
  for (auto part = parts.rbegin(); part != parts.rend(); ++part)
    list.insert(list.end(), part->begin() + 1, part->end());
  return list;
}

void BucketSpill::readBucket(size_t bucket, std::vector<std::byte>& out, SpillCodec& codec) const {
  settle();
  size_t at = out.size();
  out.resize(at + records_[bucket] * recordBytes_);
  if (lists_) {
    for (const SpillBlock& block : blockList(bucket, codec)) {
      file_->read(block, std::span<std::byte>(out.data() + at, block.rawBytes), codec);
      at += block.rawBytes;
    }
  }
  // Straight into `out`: no block of scratch beyond the codec's compressed one.
  for (uint32_t b = head_[bucket]; b != kNoBlock; b = blocks_[b].next) {
    const SpillBlock& block = blocks_[b].block;
    file_->read(block, std::span<std::byte>(out.data() + at, block.rawBytes), codec);
    at += block.rawBytes;
  }
  if (fill_[bucket] > 0) std::memcpy(out.data() + at, buffer_.get() + bucket * bufferBytes_, fill_[bucket]);
}

}  // namespace facetree
