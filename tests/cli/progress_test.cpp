// The progress display of `facetree build -o`: drawn on stderr when stderr is a
// terminal (each phase with its share done, its rate and an ETA, redrawn in place on one line,
// cleared at the end), and absent when it is not, so logs and pipes stay clean.
#include <gtest/gtest.h>
#include <pty.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <filesystem>
#include <string>
#include <vector>

#include "run_cli.h"

namespace facetree {
namespace {

namespace fs = std::filesystem;

// Whether `text` contains `pattern`, in which "#" stands for one or more digits, "?" for exactly
// one digit and "_" for one or more spaces. (std::regex would do, but its inlined automaton
// trips GCC 12's -Wmaybe-uninitialized in the sanitizer build.)
bool containsShape(const std::string& text, const std::string& pattern) {
  const auto isDigit = [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; };
  const auto matchesAt = [&](size_t t) {
    for (const char p : pattern) {
      if (t >= text.size()) return false;
      if (p == '#' || p == '_') {
        const auto inRun = [&](char c) { return p == '#' ? isDigit(c) : c == ' '; };
        if (!inRun(text[t])) return false;
        while (t < text.size() && inRun(text[t])) ++t;           // greedy: a pattern never follows a run
      } else if (p == '?' ? !isDigit(text[t]) : text[t] != p) {  // with the same class
        return false;
      } else {
        ++t;
      }
    }
    return true;
  };
  for (size_t start = 0; start < text.size(); ++start)
    if (matchesAt(start)) return true;
  return false;
}

struct TerminalRun {
  int exitCode = -1;
  std::string screen;  // everything the child wrote to its terminal (stdout and stderr)
};

// Runs the executable with a pseudo-terminal as its standard input, output and error.
TerminalRun runOnTerminal(const std::vector<std::string>& args) {
  std::string program = FACETREE_CLI;
  std::vector<std::string> copies(args);
  std::vector<char*> argv{program.data()};
  for (std::string& a : copies) argv.push_back(a.data());
  argv.push_back(nullptr);
  TerminalRun run;
  int master = -1;
  const pid_t pid = ::forkpty(&master, nullptr, nullptr, nullptr);
  if (pid < 0) return run;
  if (pid == 0) {
    ::execv(program.c_str(), argv.data());
    ::_exit(127);
  }
  char buffer[4096];
  for (;;) {
    const ssize_t got = ::read(master, buffer, sizeof buffer);
    if (got > 0) {
      run.screen.append(buffer, static_cast<size_t>(got));
    } else if (got < 0 && errno == EINTR) {
      continue;
    } else {
      break;  // EIO once the child has closed its side
    }
  }
  ::close(master);
  int status = 0;
  ::waitpid(pid, &status, 0);
  run.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

class Progress : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("facetree_progress_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    mesh_ = dir_ / "terrain.ply";
    const auto made = test::runCli("gen terrain -n 200000 -o " + mesh_.string());
    ASSERT_EQ(made.exitCode, 0) << made.out;
  }
  void TearDown() override { fs::remove_all(dir_); }

  // An out-of-core build (forced by small cells), so that every phase of the job is shown.
  std::vector<std::string> buildArgs(const fs::path& out) const {
    return {"build", mesh_.string(), "-o", out.string(), "--memory", "64M", "--cell-faces", "20000"};
  }

  fs::path dir_, mesh_;
};

TEST_F(Progress, DrawnOnATerminalWithPhaseRateAndEta) {
  const TerminalRun run = runOnTerminal(buildArgs(dir_ / "tty.fch"));
  ASSERT_EQ(run.exitCode, 0) << run.screen;
  // A binary PLY is read in ranges of known faces: its read has a share done too.
  for (const char* phase : {"read", "bin", "cells", "write"}) {
    // "\r" redraws in place: the phase, its share done, faces (or items) per second, ETA.
    const std::string line = std::string("\r") + phase + "_#.?% _#.?? M/s  ETA_# s  (# s total)";
    EXPECT_TRUE(containsShape(run.screen, line)) << phase << " not shown in:\n" << run.screen;
  }
  // Read whole (--weld reads the file through the stream), reading shows the bytes read so far.
  std::vector<std::string> weld = buildArgs(dir_ / "weld.fch");
  weld.push_back("--weld");
  const TerminalRun streamed = runOnTerminal(weld);
  ASSERT_EQ(streamed.exitCode, 0) << streamed.screen;
  EXPECT_TRUE(containsShape(streamed.screen, "\rread_#.? MB  (# s total)"))
      << "reading shows the bytes read so far:\n"
      << streamed.screen;
  // The line is blanked before the summary is printed.
  const size_t cleared = run.screen.rfind("\r" + std::string(70, ' ') + "\r");
  ASSERT_NE(cleared, std::string::npos) << run.screen;
  EXPECT_EQ(run.screen.find(" M/s  ETA ", cleared), std::string::npos) << "drawn again after clearing";
  EXPECT_TRUE(fs::exists(dir_ / "tty.fch"));
}

TEST_F(Progress, AbsentWhenStandardErrorIsNotATerminal) {
  const auto run = test::runCli([&] {
    std::string command;
    for (const std::string& a : buildArgs(dir_ / "pipe.fch")) command += a + " ";
    return command;
  }());
  ASSERT_EQ(run.exitCode, 0) << run.out;
  EXPECT_EQ(run.out.find('\r'), std::string::npos) << run.out;
  EXPECT_EQ(run.out.find("ETA"), std::string::npos) << run.out;
  // ... and --json on a terminal prints the report alone (stdout is then a document).
  const TerminalRun json = [&] {
    auto args = buildArgs(dir_ / "json.fch");
    args.push_back("--json");
    return runOnTerminal(args);
  }();
  ASSERT_EQ(json.exitCode, 0) << json.screen;
  EXPECT_EQ(json.screen.find("ETA"), std::string::npos) << json.screen;
  EXPECT_EQ(json.screen.find('{'), 0u) << json.screen;
}

}  // namespace
}  // namespace facetree
