// SIGINT, SIGTERM and SIGHUP for the facetree executable: the signals are blocked in every
// thread and taken by one sigwait thread, which sets a flag the long loops poll (through the
// library's cancellation hooks: BuildOptions::cancelled, LoadOptions::cancelled). The work
// then unwinds by itself (Cancelled), its writers removing their temporary files, and main()
// exits with 128 + the signal. If it has not finished unwinding within the grace time (a loop
// that does not poll, or a second signal), the thread removes the registered temporary paths
// and ends the process with _exit(128 + signal).
//
// Contract: exit 0 means every output is complete; 130/143/129 means no output appeared under
// its final name (the outputs are renamed into place only when complete) and no temporary
// file is left.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace facetree::cli {

class SignalGuard {
 public:
  // Time the work has to unwind after the first signal before the forced exit.
  static constexpr std::chrono::milliseconds kDefaultGrace{1000};

  // Blocks the signals in the calling thread (construct it before any other thread starts, so
  // that they all inherit the mask) and starts the sigwait thread.
  explicit SignalGuard(std::chrono::milliseconds grace = kDefaultGrace);
  // Stops the sigwait thread; the signals stay blocked (the process is about to exit).
  ~SignalGuard();
  SignalGuard(const SignalGuard&) = delete;
  SignalGuard& operator=(const SignalGuard&) = delete;

  // The first signal received, or 0.
  int signal() const { return signal_.load(std::memory_order_acquire); }
  // A hook for the library's options: true once a signal has been received.
  std::function<bool()> cancelHook() const {
    return [this] { return signal() != 0; };
  }

  // `path` is about to be written through the io/ writers: their temporary file
  // (temporaryOutputPath) is removed on a forced exit. A named pipe is written in place instead
  // (isStreamOutput); a reader already waiting on it is let in and sees end of file when the
  // guard ends, whether or not the command wrote anything.
  void guardOutput(const std::filesystem::path& path);
  // A temporary file or folder (spills) removed, recursively, on a forced exit; the owner still
  // removes it on every other path. Thread-safe.
  void guardTemporary(const std::filesystem::path& path);
  void releaseTemporary(const std::filesystem::path& path);

 private:
  void waitForSignals();
  [[noreturn]] void forceExit(int signal);

  const std::chrono::milliseconds grace_;
  std::atomic<int> signal_{0};
  std::mutex mutex_;  // guards the fields below
  std::condition_variable finishedChanged_;
  bool finished_ = false;
  std::vector<std::filesystem::path> temporaries_;
  std::vector<int> streams_;  // named pipes held open for their readers (guardOutput)
  std::jthread waiter_;       // last: started once the fields above exist
};

// "SIGINT" for SIGINT, etc.
const char* signalName(int signal);

}  // namespace facetree::cli
