// Helpers of the spill tests: a scratch parent directory and a forked child process.
#pragma once

#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <exception>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace facetree::test {

// A fresh directory under the system temporary directory, removed with its contents at the end.
class ScratchDir {
 public:
  ScratchDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "facetree-spilltest-XXXXXX").string();
    if (!mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~ScratchDir() {
    std::error_code ignored;
    std::filesystem::permissions(path_, std::filesystem::perms::owner_all, ignored);
    std::filesystem::remove_all(path_, ignored);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  bool empty() const { return std::filesystem::is_empty(path_); }

 private:
  std::filesystem::path path_;
};

// Runs body(0) on another thread while body(1) runs on this one (readers of one spill at the same
// time) and returns the mismatches each counted.
inline std::pair<int, int> mismatchesOnTwoThreads(const std::function<int(unsigned)>& body) {
  int other = 0;
  std::thread thread([&] { other = body(0); });
  const int here = body(1);
  thread.join();
  return {other, here};
}

struct ChildResult {
  int exitCode = -1;   // -1 when the child did not exit normally
  std::string output;  // what the child's function returned
};

// The parent's side of a forked child writing to fds[1]: reads everything it writes, then waits
// for its exit code.
inline ChildResult collectChild(pid_t pid, int fds[2]) {
  close(fds[1]);
  ChildResult result;
  char buffer[4096];
  for (ssize_t got; (got = read(fds[0], buffer, sizeof buffer)) != 0;) {
    if (got > 0)
      result.output.append(buffer, static_cast<size_t>(got));
    else if (errno != EINTR)
      break;
  }
  close(fds[0]);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status)) result.exitCode = WEXITSTATUS(status);
  return result;
}

// Forks with a pipe from the child (writing fds[1]) to the parent (reading fds[0], through
// collectChild); returns fork()'s result, with the parent's end already closed in the child.
inline pid_t forkWithPipe(int fds[2]) {
  if (pipe(fds) != 0) throw std::runtime_error("pipe failed");
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) close(fds[0]);
  return pid;
}

// Runs `body` in a forked child (for process-wide limits: RLIMIT_FSIZE, peak RSS) and returns what it
// returned. An exception in the child becomes exit code 2 with its what() as output.
inline ChildResult runInChild(const std::function<std::string()>& body) {
  int fds[2];
  const pid_t pid = forkWithPipe(fds);
  if (pid == 0) {
    std::string output;
    int code = 0;
    try {
      output = body();
    } catch (const std::exception& e) {
      output = std::string("exception: ") + e.what();
      code = 2;
    }
    for (size_t done = 0; done < output.size();) {
      const ssize_t got = write(fds[1], output.data() + done, output.size() - done);
      if (got <= 0) _exit(3);
      done += static_cast<size_t>(got);
    }
    _exit(code);  // no gtest teardown, no atexit handlers of the parent's state
  }
  return collectChild(pid, fds);
}

// Runs the program argv[0] with its arguments and returns its exit code and standard output.
inline ChildResult runProgram(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  int fds[2];
  const pid_t pid = forkWithPipe(fds);
  if (pid == 0) {
    dup2(fds[1], STDOUT_FILENO);
    execv(args[0], args.data());
    _exit(127);
  }
  return collectChild(pid, fds);
}

}  // namespace facetree::test
