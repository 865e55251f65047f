// SignalGuard (signals.h): the sigwait thread, the flag the work polls, and the last-resort
// removal of outputs and temporary files when a signal ends the process.
#include "signals.h"

#include <fcntl.h>
#include <pthread.h>
#include <unistd.h>

#include <csignal>
#include <cstring>
#include <string>
#include <system_error>

#include "facetree/io.h"

namespace facetree::cli {
namespace {

sigset_t handledSignals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGHUP);
  return set;
}

}  // namespace

const char* signalName(int signal) {
  switch (signal) {
    case SIGINT:
      return "SIGINT";
    case SIGTERM:
      return "SIGTERM";
    case SIGHUP:
      return "SIGHUP";
  }
  return "a signal";
}

SignalGuard::SignalGuard(std::chrono::milliseconds grace) : grace_(grace) {
  const sigset_t set = handledSignals();
  if (const int error = pthread_sigmask(SIG_BLOCK, &set, nullptr); error != 0)
    throw std::system_error(error, std::generic_category(), "pthread_sigmask");
  waiter_ = std::jthread([this] { waitForSignals(); });
}

SignalGuard::~SignalGuard() {
  {
    std::lock_guard lock(mutex_);
    finished_ = true;
  }
  finishedChanged_.notify_all();
  // Still in sigwait (no signal taken yet): wake it with a signal aimed at it alone, which it
  // takes and, seeing finished_, returns. After a signal it never waits again.
  if (signal() == 0) pthread_kill(waiter_.native_handle(), SIGINT);
  for (const int fd : streams_) ::close(fd);
}

void SignalGuard::guardOutput(const std::filesystem::path& path) {
  std::error_code ignored;
  if (std::filesystem::is_fifo(path, ignored)) {
    // A reader already waiting on the pipe is let in now (without waiting for one) and the pipe
    // is held open until the process ends: the reader then sees end of file however the command
    // ends, also when it fails before its writer opens the pipe.
    const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd >= 0) {
      std::lock_guard lock(mutex_);
      streams_.push_back(fd);
    }
    return;
  }
  if (isStreamOutput(path)) return;
  guardTemporary(temporaryOutputPath(path));
}

void SignalGuard::guardTemporary(const std::filesystem::path& path) {
  std::lock_guard lock(mutex_);
  temporaries_.push_back(path);
}

void SignalGuard::releaseTemporary(const std::filesystem::path& path) {
  std::lock_guard lock(mutex_);
  std::erase(temporaries_, path);
}

void SignalGuard::waitForSignals() {
  const sigset_t set = handledSignals();
  int taken = 0;
  while (sigwait(&set, &taken) != 0) {
  }
  std::unique_lock lock(mutex_);
  if (finished_) return;  // the wake-up from the destructor (or a signal after the work ended)
  signal_.store(taken, std::memory_order_release);
  if (finishedChanged_.wait_for(lock, grace_, [this] { return finished_; })) return;
  forceExit(taken);  // with the lock held: no path is added or released meanwhile
}

void SignalGuard::forceExit(int signal) {
  for (const std::filesystem::path& path : temporaries_) {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
  // write(2), not stdio: the main thread may hold stderr's lock.
  const std::string message = std::string("facetree: interrupted by ") + signalName(signal) + "\n";
  [[maybe_unused]] const ssize_t written = ::write(STDERR_FILENO, message.data(), message.size());
  ::_exit(128 + signal);
}

}  // namespace facetree::cli
