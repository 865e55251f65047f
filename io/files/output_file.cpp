// OutputFile (facetree/io.h): writing under a temporary name, syncing and renaming into place;
// and the checks every output shares (stream outputs, an output that cannot be created).

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "facetree/io.h"

namespace facetree {
namespace {
constexpr size_t kBufferBytes = size_t{1} << 20;
// Written bytes are handed to the disk every this many (Linux: sync_file_range), so that the sync
// at commit waits for the last few MiB instead of the whole file (RocksDB's bytes_per_sync): a
// file of tens of MB otherwise ends with a sync of tens of milliseconds.
constexpr uint64_t kWritebackBytes = uint64_t{8} << 20;

}  // namespace

std::filesystem::path temporaryOutputPath(const std::filesystem::path& path) {
  // Unique per process so that two runs writing the same target do not collide.
  return std::filesystem::path(path.string() + ".tmp" + std::to_string(::getpid()));
}

void OutputFile::Closer::operator()(std::FILE* f) const {
  if (f != stdout) std::fclose(f);
}

bool isStreamOutput(const std::filesystem::path& path) {
  if (path == "-") return true;
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  return !error && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status) &&
         !std::filesystem::is_directory(status);
}

OutputFile::OutputFile(const std::filesystem::path& path) : path_(path) {
  if (path == "-") {
    stream_ = true;
    file_.reset(stdout);
    return;
  }
  if (isStreamOutput(path)) {
    stream_ = true;
    file_.reset(std::fopen(path.c_str(), "wb"));
    if (!file_) fail("cannot open");
    std::setvbuf(file_.get(), nullptr, _IOFBF, kBufferBytes);
    return;
  }
  temporary_ = temporaryOutputPath(path);
  file_.reset(std::fopen(temporary_.c_str(), "wb"));
  if (!file_) fail("cannot create");
  std::setvbuf(file_.get(), nullptr, _IOFBF, kBufferBytes);
}

OutputFile::~OutputFile() {
  if (!committed_ && !stream_) {
    file_.reset();
    std::error_code ignored;
    std::filesystem::remove(temporary_, ignored);
  }
}

void OutputFile::fail(const char* what) const {
  const int error = errno;
  throw Error(ErrorCategory::Output,
              path_.string() + ": " + what + ": " + (error ? std::strerror(error) : "write error"));
}

void OutputFile::write(const void* data, size_t bytes) {
  if (bytes == 0) return;
  if (std::fwrite(data, 1, bytes, file_.get()) != bytes) fail("cannot write");
  written_ += bytes;
  if (!stream_ && written_ - handedToDisk_ >= kWritebackBytes) startWriteback();
}

void OutputFile::startWriteback() {
#if defined(__linux__)
  if (std::fflush(file_.get()) != 0) fail("cannot write");
  // Starts the writeback and returns; errors surface at commit's fsync.
  ::sync_file_range(::fileno(file_.get()), static_cast<off_t>(handedToDisk_),
                    static_cast<off_t>(written_ - handedToDisk_), SYNC_FILE_RANGE_WRITE);
#endif
  handedToDisk_ = written_;
}

void OutputFile::writeAt(uint64_t offset, std::string_view bytes) {
  if (stream_) throw std::logic_error("OutputFile::writeAt: a stream cannot seek");
  if (offset + bytes.size() > written_)
    throw std::logic_error("OutputFile::writeAt: beyond the bytes written");
  if (std::fflush(file_.get()) != 0 || ::fseeko(file_.get(), static_cast<off_t>(offset), SEEK_SET) != 0 ||
      std::fwrite(bytes.data(), 1, bytes.size(), file_.get()) != bytes.size() ||
      std::fflush(file_.get()) != 0 || ::fseeko(file_.get(), 0, SEEK_END) != 0)
    fail("cannot write");
}

void OutputFile::commit() {
  if (std::fflush(file_.get()) != 0) fail("cannot write");
  if (stream_) {
    if (file_.get() != stdout && std::fclose(file_.release()) != 0) fail("cannot close");
    committed_ = true;
    return;
  }
  if (::fsync(::fileno(file_.get())) != 0 && errno != EINVAL) fail("cannot sync");
  std::FILE* f = file_.release();
  if (std::fclose(f) != 0) fail("cannot close");
  std::error_code error;
  std::filesystem::rename(temporary_, path_, error);
  if (error) {
    const std::string reason = error.message();
    std::filesystem::remove(temporary_, error);
    throw Error(ErrorCategory::Output, path_.string() + ": cannot rename temporary file: " + reason);
  }
  committed_ = true;
}

void checkOutputWritable(const std::filesystem::path& path) {
  if (isStreamOutput(path)) return;  // written in place: nothing to create beside it
  std::error_code ignored;
  int error = 0;
  if (std::filesystem::is_directory(path, ignored)) {
    error = EISDIR;
  } else {
    const std::filesystem::path parent = path.has_parent_path() ? path.parent_path() : ".";
    if (::access(parent.c_str(), W_OK | X_OK) != 0) error = errno;
  }
  // The message OutputFile gives when it cannot create the file.
  if (error != 0)
    throw Error(ErrorCategory::Output, path.string() + ": cannot create: " + std::strerror(error));
}

}  // namespace facetree
