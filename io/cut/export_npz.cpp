// writeCutNpz: a cut's clusters as NumPy arrays in a .npz, the archive numpy.load reads: a ZIP of
// stored (uncompressed) members, one .npy each (NumPy's format 1.0: magic, a header dict padded
// to 64 bytes, the array's little-endian bytes in C order). Members are built one at a time, so
// the writer holds one array beside the cut.
#include <array>
#include <bit>
#include <limits>
#include <string>

#include "facetree/error.h"
#include "facetree/io.h"
#include "format/fch_format.h"

namespace facetree {
namespace {

static_assert(std::endian::native == std::endian::little, "the arrays are written in host order");

// CRC-32 of ZIP (IEEE 802.3, reflected 0xEDB88320).
uint32_t crc32(const std::string& bytes) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = c & 1 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  uint32_t c = 0xFFFFFFFFu;
  for (const char b : bytes) c = table[(c ^ static_cast<uint8_t>(b)) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

using fch::put;

// A .npy of `rows` x `columns` (columns 1: a vector) of dtype `descr`, its data from fill(out).
template <class T, class Fill>
std::string npy(const char* descr, uint64_t rows, unsigned columns, Fill&& fill) {
  std::string header = std::string("{'descr': '") + descr + "', 'fortran_order': False, 'shape': (" +
                       std::to_string(rows) + (columns == 1 ? "," : ", " + std::to_string(columns)) + "), }";
  const size_t unpadded = 10 + header.size() + 1;  // magic, version, length; the dict; '\n'
  header.append((64 - unpadded % 64) % 64, ' ');
  header += '\n';
  std::string out("\x93NUMPY\x01\x00", 8);
  put<uint16_t>(out, static_cast<uint16_t>(header.size()));
  out += header;
  out.reserve(out.size() + rows * columns * sizeof(T));
  fill(out);
  return out;
}

class NpzArchive {
 public:
  explicit NpzArchive(const std::filesystem::path& path) : file_(path) {}
  void add(const std::string& name, const std::string& data) {
    const uint64_t offset = file_.bytesWritten();
    if (offset + data.size() + 100 > std::numeric_limits<uint32_t>::max())
      throw Error(ErrorCategory::Output, file_.path().string() +
                                             ": the cut's arrays pass 4 GiB, more than a .npz without ZIP64 "
                                             "holds: write JSON lines instead");
    const uint32_t crc = crc32(data);
    const std::string member = name + ".npy";
    std::string local;
    put<uint32_t>(local, 0x04034b50);
    put<uint16_t>(local, 20);    // version needed
    put<uint16_t>(local, 0);     // flags
    put<uint16_t>(local, 0);     // stored
    put<uint16_t>(local, 0);     // time
    put<uint16_t>(local, 0x21);  // 1980-01-01
    put<uint32_t>(local, crc);
    put<uint32_t>(local, static_cast<uint32_t>(data.size()));
    put<uint32_t>(local, static_cast<uint32_t>(data.size()));
    put<uint16_t>(local, static_cast<uint16_t>(member.size()));
    put<uint16_t>(local, 0);
    local += member;
    file_.write(local);
    file_.write(data);

    put<uint32_t>(central_, 0x02014b50);
    put<uint16_t>(central_, 20);    // made by
    central_.append(local, 4, 26);  // version needed ... extra length, as in the local header
    put<uint16_t>(central_, 0);     // comment
    put<uint16_t>(central_, 0);     // disk
    put<uint16_t>(central_, 0);     // internal attributes
    put<uint32_t>(central_, 0);     // external attributes
    put<uint32_t>(central_, static_cast<uint32_t>(offset));
    central_ += member;
    ++members_;
  }
  void commit() {
    const uint64_t offset = file_.bytesWritten();
    file_.write(central_);
    std::string end;
    put<uint32_t>(end, 0x06054b50);
    put<uint16_t>(end, 0);
    put<uint16_t>(end, 0);
    put<uint16_t>(end, members_);
    put<uint16_t>(end, members_);
    put<uint32_t>(end, static_cast<uint32_t>(central_.size()));
    put<uint32_t>(end, static_cast<uint32_t>(offset));
    put<uint16_t>(end, 0);
    file_.write(end);
    file_.commit();
  }

 private:
  OutputFile file_;
  std::string central_;
  uint16_t members_ = 0;
};

}  // namespace

void writeCutNpz(const std::filesystem::path& path, std::span<const CutCluster> cut,
                 std::span<const FchNode> records) {
  if (records.size() != cut.size())
    throw std::invalid_argument("writeCutNpz: " + std::to_string(records.size()) + " records for " +
                                std::to_string(cut.size()) + " clusters");
  const uint64_t n = cut.size();
  const auto hasNode = [&](size_t i) { return cut[i].node != kNoNode; };
  NpzArchive npz(path);
  npz.add("node", npy<int64_t>("<i8", n, 1, [&](std::string& out) {
            for (size_t i = 0; i < n; ++i)
              put<int64_t>(out, hasNode(i) ? static_cast<int64_t>(cut[i].node) : -1);
          }));
  npz.add("first", npy<uint64_t>("<u8", n, 1, [&](std::string& out) {
            for (const CutCluster& c : cut) put<uint64_t>(out, c.first);
          }));
  npz.add("triangles", npy<uint64_t>("<u8", n, 1, [&](std::string& out) {
            for (const CutCluster& c : cut) put<uint64_t>(out, c.count);
          }));
  const float none = std::numeric_limits<float>::quiet_NaN();
  const auto column = [&](const char* name, unsigned columns, auto value) {
    npz.add(name, npy<float>("<f4", n, columns, [&](std::string& out) {
              for (size_t i = 0; i < n; ++i)
                for (unsigned k = 0; k < columns; ++k)
                  put<float>(out, hasNode(i) ? value(records[i], k) : none);
            }));
  };
  column("cost", 1, [](const FchNode& r, unsigned) { return r.cost; });
  column("area", 1, [](const FchNode& r, unsigned) { return r.area; });
  column("perimeter", 1, [](const FchNode& r, unsigned) { return r.perimeter; });
  column("center", 3, [](const FchNode& r, unsigned k) { return r.box.center[static_cast<int>(k)]; });
  column("half_extents", 3,
         [](const FchNode& r, unsigned k) { return r.box.halfExtent[static_cast<int>(k)]; });
  column("orientation", 4, [](const FchNode& r, unsigned k) {
    const glm::quat& q = r.box.orientation;
    return k == 0 ? q.x : k == 1 ? q.y : k == 2 ? q.z : q.w;
  });
  npz.commit();
}

}  // namespace facetree
