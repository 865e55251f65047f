// Runs the facetree executable as a child process the test controls: resource limits
// (RLIMIT_FSIZE with SIGXFSZ ignored, RLIMIT_STACK), standard input from a file or a pipe,
// signals sent mid-run. stdout and stderr go to one file, read back by wait().
#pragma once

#include <fcntl.h>
#include <grp.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace facetree::test {

// The bytes of a file (empty when it cannot be read).
inline std::string fileBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

struct ChildOptions {
  std::optional<rlim_t> fileSizeLimit;  // bytes; writes beyond fail with EFBIG
  std::optional<rlim_t> stackLimit;     // bytes, for the main thread and new threads
  std::string stdinPath;                // empty: /dev/null (unless stdinPipe)
  bool stdinPipe = false;               // feed standard input through writeInput()
  // Run the child as this user id (with the same group id and no supplementary groups). For a
  // parent running as root, whose file accesses permission bits do not stop: CI runs as root.
  std::optional<uid_t> user;
};

// The unprivileged user that permission tests run their child as when the suite runs as root.
inline constexpr uid_t kNobody = 65534;

struct ChildResult {
  int exitCode = -1;   // when the child exited
  int termSignal = 0;  // when a signal killed it
  std::string output;  // stdout and stderr, merged
};

class Child {
 public:
  Child(const std::vector<std::string>& args, const ChildOptions& options = {}) {
    outputPath_ = std::filesystem::temp_directory_path() /
                  ("facetree_child_" + std::to_string(::getpid()) + "_" +
                   std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()));
    // Everything the child needs is prepared before fork: after it, only async-signal-safe calls.
    std::string program = FACETREE_CLI;
    std::vector<std::string> copies(args);
    std::vector<char*> argv{program.data()};
    for (std::string& a : copies) argv.push_back(a.data());
    argv.push_back(nullptr);
    const std::string stdinPath = options.stdinPath.empty() ? "/dev/null" : options.stdinPath;
    int pipeFds[2] = {-1, -1};
    if (options.stdinPipe && ::pipe(pipeFds) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      const int out = ::open(outputPath_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int in = options.stdinPipe ? pipeFds[0] : ::open(stdinPath.c_str(), O_RDONLY);
      if (out < 0 || in < 0) ::_exit(126);
      ::dup2(in, 0), ::dup2(out, 1), ::dup2(out, 2);
      if (options.stdinPipe) ::close(pipeFds[1]);
      if (options.fileSizeLimit) {
        const rlimit limit{*options.fileSizeLimit, *options.fileSizeLimit};
        ::setrlimit(RLIMIT_FSIZE, &limit);
        ::signal(SIGXFSZ, SIG_IGN);  // an ignored disposition survives exec: writes fail with EFBIG
      }
      if (options.stackLimit) {
        const rlimit limit{*options.stackLimit, *options.stackLimit};
        ::setrlimit(RLIMIT_STACK, &limit);
      }
      if (options.user) {
        const auto id = static_cast<gid_t>(*options.user);
        if (::setgroups(0, nullptr) != 0 || ::setgid(id) != 0 || ::setuid(*options.user) != 0) ::_exit(125);
      }
      sigset_t none;
      sigemptyset(&none);
      ::sigprocmask(SIG_SETMASK, &none, nullptr);
      ::execv(program.c_str(), argv.data());
      ::_exit(127);
    }
    if (options.stdinPipe) {
      ::close(pipeFds[0]);
      input_ = pipeFds[1];
    }
  }
  ~Child() {
    closeInput();
    if (pid_ > 0 && !finished_) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      ::waitpid(pid_, &status, 0);
    }
    std::error_code ignored;
    std::filesystem::remove(outputPath_, ignored);
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  bool started() const { return pid_ > 0; }
  pid_t pid() const { return pid_; }
  // Writes all of `path` to the child's standard input (blocks while the child does not read);
  // false if the child stopped reading.
  bool writeInput(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::vector<char> buffer(1 << 16);
    const sighandler_t old = ::signal(SIGPIPE, SIG_IGN);
    bool ok = true;
    while (ok && in) {
      in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      const char* p = buffer.data();
      for (std::streamsize left = in.gcount(); left > 0;) {
        const ssize_t n = ::write(input_, p, static_cast<size_t>(left));
        if (n <= 0) {
          ok = false;
          break;
        }
        p += n, left -= n;
      }
    }
    ::signal(SIGPIPE, old);
    return ok;
  }
  void closeInput() {
    if (input_ >= 0) ::close(input_), input_ = -1;
  }
  // True while the child has not exited (reaps it when it has).
  bool running() {
    if (finished_) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      record(status);
      return false;
    }
    return true;
  }
  void signal(int sig) { ::kill(pid_, sig); }
  // Waits for the exit. `hangLimit` only guards the test suite against a hung child (it is
  // killed and the result shows termSignal SIGKILL); it is not a timing requirement.
  ChildResult wait(std::chrono::seconds hangLimit = std::chrono::seconds(300)) {
    const auto deadline = std::chrono::steady_clock::now() + hangLimit;
    while (running()) {
      if (std::chrono::steady_clock::now() > deadline) ::kill(pid_, SIGKILL);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    std::ifstream in(outputPath_, std::ios::binary);
    result_.output.assign(std::istreambuf_iterator<char>(in), {});
    return result_;
  }

 private:
  void record(int status) {
    finished_ = true;
    if (WIFEXITED(status)) result_.exitCode = WEXITSTATUS(status);
    if (WIFSIGNALED(status)) result_.termSignal = WTERMSIG(status);
  }
  pid_t pid_ = -1;
  int input_ = -1;
  bool finished_ = false;
  std::filesystem::path outputPath_;
  ChildResult result_;
};

inline ChildResult runChild(const std::vector<std::string>& args, const ChildOptions& options = {}) {
  Child child(args, options);
  return child.wait();
}

}  // namespace facetree::test
