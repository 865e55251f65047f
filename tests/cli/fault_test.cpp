// Faults injected into the facetree executable: the disk filling up while an output is written
// (RLIMIT_FSIZE), unreadable inputs, unwritable output folders, and SIGINT / SIGTERM mid-run.
// Every case checks the exit code, the exact message, and that the output folder holds neither
// the output nor a temporary file afterwards.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "child_process.h"
#include "run_cli.h"

namespace facetree {
namespace {

namespace fs = std::filesystem;
using test::Child;
using test::ChildOptions;
using test::ChildResult;
using test::fileBytes;
using test::runChild;

// Small enough that every output below exceeds it (each case checks that it does).
constexpr rlim_t kFileSizeLimit = 16 * 1024;

std::vector<std::string> listing(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename().string());
  return names;
}

// Shared inputs: a mesh and its cluster file, made once for the suite.
class Faults : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    inputs_ = fs::temp_directory_path() / ("facetree_faults_" + std::to_string(::getpid()));
    fs::create_directories(inputs_);
    ASSERT_EQ(test::runCli("gen sphere -n 20000 -o " + mesh()).exitCode, 0);
    ASSERT_EQ(test::runCli("build " + mesh() + " -o " + fch()).exitCode, 0);
  }
  static void TearDownTestSuite() { fs::remove_all(inputs_); }
  static std::string mesh() { return (inputs_ / "sphere.ply").string(); }
  static std::string fch() { return (inputs_ / "sphere.fch").string(); }

  void SetUp() override {
    out_ = inputs_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(out_);
  }
  void TearDown() override {
    fs::permissions(out_, fs::perms::owner_all, fs::perm_options::add);
    fs::remove_all(out_);
  }
  std::string out(const std::string& name) const { return (out_ / name).string(); }
  // The output folder is empty: no output and no temporary file.
  void expectNothingLeft() const {
    const auto names = listing(out_);
    EXPECT_TRUE(names.empty()) << "left behind: " << ::testing::PrintToString(names);
  }

  static inline fs::path inputs_;
  fs::path out_;
};

struct DiskFullCase {
  const char* name;
  std::vector<std::string> (*args)(const std::string& mesh, const std::string& fch, const std::string& out);
  const char* output;
};

const DiskFullCase kDiskFullCases[] = {
    {"gen",
     [](auto&, auto&, auto& o) -> std::vector<std::string> { return {"gen", "grid", "-n", "50k", "-o", o}; },
     "grid.ply"},
    {"build",
     [](auto& m, auto&, auto& o) -> std::vector<std::string> {
       return {"build", m, "-o", o};
     },
     "s.fch"},
    {"build_mesh_out",
     [](auto& m, auto&, auto& o) -> std::vector<std::string> {
       return {"build", m, "--mesh-out", o};
     },
     "reordered.ply"},
    {"truncate",
     [](auto&, auto& f, auto& o) -> std::vector<std::string> {
       return {"truncate", f, "-o", o, "--nodes", "5000"};
     },
     "t.fch"},
    {"export",
     [](auto&, auto& f, auto& o) -> std::vector<std::string> {
       return {"export", f, "--cut", "50", "-o", o};
     },
     "cut.ply"},
    {"render",
     [](auto&, auto& f, auto& o) -> std::vector<std::string> {
       return {"render", f, "--cut", "50", "-o", o};
     },
     "cut.png"},
};

TEST_F(Faults, DiskFullWhileWritingExitsWithFourAndLeavesNothing) {
  for (const DiskFullCase& c : kDiskFullCases) {
    SCOPED_TRACE(c.name);
    // Unlimited, the output is larger than the limit ...
    const std::string reference = out(std::string("ref_") + c.output);
    const ChildResult full = runChild(c.args(mesh(), fch(), reference));
    ASSERT_EQ(full.exitCode, 0) << full.output;
    ASSERT_GT(fs::file_size(reference), kFileSizeLimit);
    fs::remove(reference);
    // ... so with the limit the write fails: one message naming the file, nothing left.
    const std::string target = out(c.output);
    ChildOptions options;
    options.fileSizeLimit = kFileSizeLimit;
    const ChildResult result = runChild(c.args(mesh(), fch(), target), options);
    EXPECT_EQ(result.exitCode, 4) << result.output;
    EXPECT_EQ(result.output, "facetree: " + target + ": cannot write: File too large\n");
    expectNothingLeft();
  }
}

TEST_F(Faults, UnreadableInputExitsWithThreeAndNamesTheFile) {
  const std::string dir = out("a_folder");
  fs::create_directory(dir);
  const std::string missing = out("missing.ply");
  const std::string sink = out("sink");  // never written: every command fails first
  struct Case {
    std::vector<std::string> args;
    std::string message;
  };
  const std::vector<Case> cases = {
      {{"stats", dir}, dir + ": byte 0: is a directory"},
      {{"build", dir}, dir + ": byte 0: is a directory"},
      {{"gen", "subdivide", dir, "-o", sink}, dir + ": byte 0: is a directory"},
      {{"info", dir}, dir + ": is a directory"},
      {{"verify", dir}, dir + ": is a directory"},
      {{"truncate", dir, "-o", sink, "--nodes", "3"}, dir + ": is a directory"},
      {{"render", dir, "-o", sink}, dir + ": is a directory"},
      {{"export", dir, "-o", sink}, dir + ": is a directory"},
      {{"verify", fch(), dir}, dir + ": byte 0: is a directory"},
      {{"stats", missing}, missing + ": byte 0: cannot open: no such file or directory"},
      {{"build", missing, "-o", sink}, missing + ": byte 0: cannot open: no such file or directory"},
      {{"info", missing}, missing + ": cannot open: No such file or directory"},
      {{"export", missing, "-o", sink}, missing + ": cannot open: No such file or directory"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(::testing::PrintToString(c.args));
    const ChildResult result = runChild(c.args);
    EXPECT_EQ(result.exitCode, 3) << result.output;
    EXPECT_EQ(result.output, "facetree: " + c.message + "\n");
  }
  fs::remove(dir);
  expectNothingLeft();
}

// Options for a child whose file accesses must meet permission bits: as root (CI), it runs as
// nobody, which needs the executable and the test folders to be reachable by others.
ChildOptions unprivileged() {
  ChildOptions options;
  if (::geteuid() == 0) options.user = test::kNobody;
  return options;
}

// Whether nobody can reach and run `path` (every folder on the way searchable by others).
bool othersCanRun(fs::path path) {
  if ((fs::status(path).permissions() & fs::perms::others_exec) == fs::perms::none) return false;
  for (path = path.parent_path(); !path.empty() && path != path.root_path(); path = path.parent_path())
    if ((fs::status(path).permissions() & fs::perms::others_exec) == fs::perms::none) return false;
  return true;
}

TEST_F(Faults, InputWithoutReadPermissionExitsWithThree) {
  if (::geteuid() == 0 && !(othersCanRun(FACETREE_CLI) && othersCanRun(out_ / "x")))
    GTEST_SKIP() << "running as root, and nobody cannot reach " << FACETREE_CLI << " or " << out_;
  const std::string locked = out("locked.ply");
  fs::copy_file(mesh(), locked);
  fs::permissions(locked, fs::perms::none);
  const ChildResult result = runChild({"stats", locked}, unprivileged());
  EXPECT_EQ(result.exitCode, 3) << result.output;
  EXPECT_EQ(result.output, "facetree: " + locked + ": byte 0: cannot open: permission denied\n");
  fs::remove(locked);
}

// The output folder is checked before the work starts (a long build must not fail at its end).
TEST_F(Faults, MissingOutputFolderExitsWithFourBeforeTheWork) {
  const std::string target = out("no_such_folder/out");
  const std::vector<std::vector<std::string>> cases = {
      {"gen", "grid", "-n", "100", "-o", target},
      {"build", mesh(), "-o", target},
      {"build", mesh(), "--mesh-out", target},
      {"truncate", fch(), "-o", target, "--nodes", "3"},
      {"render", fch(), "-o", target},
      {"export", fch(), "-o", target},
      // The input is not even read: its error would be exit 3.
      {"build", out("missing.ply"), "-o", target},
  };
  for (const auto& args : cases) {
    SCOPED_TRACE(::testing::PrintToString(args));
    const ChildResult result = runChild(args);
    EXPECT_EQ(result.exitCode, 4) << result.output;
    EXPECT_EQ(result.output, "facetree: " + target + ": cannot create: No such file or directory\n");
  }
  const ChildResult folder = runChild({"build", mesh(), "-o", out_.string()});
  EXPECT_EQ(folder.exitCode, 4) << folder.output;
  EXPECT_EQ(folder.output, "facetree: " + out_.string() + ": cannot create: Is a directory\n");
  expectNothingLeft();
}

TEST_F(Faults, UnwritableOutputFolderExitsWithFour) {
  if (::geteuid() == 0 && !(othersCanRun(FACETREE_CLI) && othersCanRun(out_ / "x")))
    GTEST_SKIP() << "running as root, and nobody cannot reach " << FACETREE_CLI << " or " << out_;
  fs::permissions(out_, fs::perms::owner_write | fs::perms::group_write | fs::perms::others_write,
                  fs::perm_options::remove);
  const std::string target = out("out.fch");
  const ChildResult result = runChild({"build", mesh(), "-o", target}, unprivileged());
  EXPECT_EQ(result.exitCode, 4) << result.output;
  EXPECT_EQ(result.output, "facetree: " + target + ": cannot create: Permission denied\n");
  fs::permissions(out_, fs::perms::owner_all, fs::perm_options::add);
  expectNothingLeft();
}

// ---------------------------------------------------------------------------------------------
// Signals

// CPU time the process has used so far (utime + stime of /proc/PID/stat), in seconds.
double cpuSeconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string stat((std::istreambuf_iterator<char>(in)), {});
  const size_t end = stat.rfind(')');  // the command name may hold spaces
  if (end == std::string::npos) return 0;
  std::istringstream fields(stat.substr(end + 2));
  std::string skip;
  for (int i = 3; i < 14; ++i) fields >> skip;  // fields 3..13
  double utime = 0, stime = 0;
  fields >> utime >> stime;
  return (utime + stime) / double(::sysconf(_SC_CLK_TCK));
}

// Out of core (forced with small cells), the temporary files are what fills the disk first:
// exit 5, one message naming the temporary file (a spill, or a manifest of the tasks that read a
// binary PLY in ranges), no output and an empty --tmp folder.
TEST_F(Faults, DiskFullInTemporaryFilesExitsWithFiveAndLeavesNothing) {
  const fs::path tmp = inputs_ / "tmp-diskfull";
  fs::create_directories(tmp);
  const std::string target = out("ooc.fch");
  ChildOptions options;
  options.fileSizeLimit = kFileSizeLimit;
  const ChildResult result =
      runChild({"build", mesh(), "-o", target, "--cell-faces", "2000", "--tmp", tmp.string()}, options);
  EXPECT_EQ(result.exitCode, 5) << result.output;
  EXPECT_EQ(result.output.rfind("facetree: " + tmp.string() + "/facetree-", 0), 0u) << result.output;
  EXPECT_TRUE(std::regex_match(result.output, std::regex("facetree: " + tmp.string() +
                                                         "/facetree-[^/]+/[^ ]+\\.(spill: write failed|"
                                                         "manifest: cannot write): File too large\n")))
      << result.output;
  EXPECT_EQ(std::count(result.output.begin(), result.output.end(), '\n'), 1) << result.output;
  expectNothingLeft();
  EXPECT_TRUE(listing(tmp).empty()) << ::testing::PrintToString(listing(tmp));
  fs::remove_all(tmp);
}

// --max-tmp: the same as a limit of the run, exit 5 with the limit in the message.
TEST_F(Faults, TemporaryLimitExitsWithFive) {
  const fs::path tmp = inputs_ / "tmp-limit";
  fs::create_directories(tmp);
  const ChildResult result = runChild({"build", mesh(), "-o", out("ooc.fch"), "--cell-faces", "2000", "--tmp",
                                       tmp.string(), "--max-tmp", "64k"});
  EXPECT_EQ(result.exitCode, 5) << result.output;
  EXPECT_NE(result.output.find("temporary files would exceed --max-tmp 65536 bytes"), std::string::npos)
      << result.output;
  expectNothingLeft();
  EXPECT_TRUE(listing(tmp).empty());
  fs::remove_all(tmp);
}

// Standard input to standard output through the out-of-core build: the bytes that come out are
// the cluster file the same build writes to a file.
TEST_F(Faults, OutOfCoreFromStandardInputToStandardOutput) {
  const std::string piped = out("piped.fch"), direct = out("direct.fch");
  // (runCli appends 2>&1 to the command line: it applies to the `true` after the build, and the
  // build's report on stderr, which must not reach the file, goes to /dev/null.)
  ASSERT_EQ(test::runCli("build - -o - --cell-faces 3000 < " + mesh() + " 2>/dev/null > " + piped + "; true")
                .exitCode,
            0);
  ASSERT_EQ(test::runCli("build " + mesh() + " -o " + direct + " --cell-faces 3000").exitCode, 0);
  std::ifstream a(piped, std::ios::binary), b(direct, std::ios::binary);
  const std::string x{std::istreambuf_iterator<char>(a), {}}, y{std::istreambuf_iterator<char>(b), {}};
  EXPECT_GT(x.size(), 10000u);
  EXPECT_EQ(x, y);
  const auto verified = test::runCli("verify " + piped + " " + mesh());
  EXPECT_EQ(verified.exitCode, 0) << verified.out;
}

// A named pipe as the output, as a pipeline uses one: the command waits for a reader (which is
// started first here), then `reader` reads the pipe to its end into OUT while `command` runs.
// Returns what the shell printed; `command`'s exit code is on its last line ("exit N").
std::string runWithPipeReader(const std::string& fifo, const std::string& readOut,
                              const std::string& command) {
  // The reader is blocked opening the pipe (wchan wait_for_partner, or any wait after 5 s)
  // before the command starts, as in `cat out.fch | consumer & facetree build MESH -o out.fch`.
  const std::string script =
      "cat " + fifo + " > " + readOut +
      " & reader=$!; (sleep 60; kill $reader) >/dev/null 2>&1 & watchdog=$!; " +
      "for i in $(seq 500); do grep -qs wait_for_partner /proc/$reader/wchan && break; sleep 0.01; done; " +
      command + "; echo exit $?; wait $reader; echo reader $?; kill $watchdog";
  return test::runShell("sh -c '" + script + "'").out;
}

// -o a named pipe: the cluster file is streamed into the pipe (in core and out of core), the same
// bytes as a file; the pipe stays a pipe and nothing else appears beside it.
TEST_F(Faults, OutputToANamedPipeIsStreamedInPlace) {
  const std::string fifo = out("out.fch");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string extra : {"", " --cell-faces 3000"}) {
    const std::string direct = (inputs_ / "direct.fch").string(), read = (inputs_ / "read.fch").string();
    ASSERT_EQ(test::runCli("build " + mesh() + " -o " + direct + extra).exitCode, 0);
    const std::string printed =
        runWithPipeReader(fifo, read, std::string(FACETREE_CLI) + " build " + mesh() + " -o " + fifo + extra);
    EXPECT_NE(printed.find("exit 0\nreader 0\n"), std::string::npos) << extra << ": " << printed;
    EXPECT_EQ(fileBytes(read), fileBytes(direct)) << extra;
    EXPECT_GT(fileBytes(read).size(), 10000u);
    EXPECT_TRUE(fs::is_fifo(fifo));
    EXPECT_EQ(listing(out_), std::vector<std::string>{"out.fch"});
    fs::remove(direct);
    fs::remove(read);
  }
}

// A build that fails with a named pipe as its output: the one error, its exit code, and the
// reader waiting on the pipe sees end of file instead of waiting forever.
TEST_F(Faults, FailedBuildIntoANamedPipeLetsItsReaderFinish) {
  const std::string fifo = out("out.fch"), bad = out("bad.ply"), read = (inputs_ / "read.fch").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::ofstream(bad)
      << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
         "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n";
  const std::string printed =
      runWithPipeReader(fifo, read, std::string(FACETREE_CLI) + " build " + bad + " -o " + fifo);
  EXPECT_NE(
      printed.find("facetree: " + bad + ": line 13: face 0: vertex index 7 out of range (3 vertices)\n"),
      std::string::npos)
      << printed;
  EXPECT_NE(printed.find("exit 3\nreader 0\n"), std::string::npos) << printed;
  EXPECT_EQ(fileBytes(read), "");
  EXPECT_TRUE(fs::is_fifo(fifo));
  fs::remove(read);
}

class Signals : public Faults, public ::testing::WithParamInterface<int> {
 protected:
  static void SetUpTestSuite() {
    Faults::SetUpTestSuite();
    // A few million faces: seconds of merging on any machine.
    ASSERT_EQ(test::runCli("gen grid -n 3M --shuffle-faces -o " + bigMesh()).exitCode, 0);
  }
  static std::string bigMesh() { return (inputs_ / "grid3m.ply").string(); }
  std::string message() const {
    return std::string("facetree: interrupted by ") + (GetParam() == SIGINT ? "SIGINT" : "SIGTERM") + "\n";
  }
  // Sends the signal once the child has worked `cpu` seconds, and checks that it stopped with
  // 128 + signal and said so.
  void interruptAfter(Child& child, double cpu) const {
    ASSERT_TRUE(child.started());
    while (child.running() && cpuSeconds(child.pid()) < cpu)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    child.signal(GetParam());
    const ChildResult result = child.wait();
    EXPECT_EQ(result.exitCode, 128 + GetParam()) << result.output;
    EXPECT_EQ(result.output, message());
  }
};

// Mid-merge (the input is all read from a pipe): the build polls the signal, unwinds, exits
// with 128 + signal and writes nothing.
TEST_P(Signals, BuildFromStandardInputStopsWithNoOutput) {
  const std::string target = out("big.fch");
  ChildOptions options;
  options.stdinPipe = true;
  Child child({"build", "-", "-o", target}, options);
  ASSERT_TRUE(child.started());
  ASSERT_TRUE(child.writeInput(bigMesh()));
  child.closeInput();
  child.signal(GetParam());
  const ChildResult result = child.wait();
  EXPECT_EQ(result.exitCode, 128 + GetParam()) << result.output;
  EXPECT_EQ(result.output, message());
  expectNothingLeft();
}

// The same from a file: the signal comes once the process has worked a little.
TEST_P(Signals, BuildFromFileStopsWithNoOutput) {
  const std::string target = out("big.fch");
  Child child({"build", bigMesh(), "-o", target, "--mesh-out", out("big.ply")});
  interruptAfter(child, 0.3);
  expectNothingLeft();
}

// Out of core: the signal stops the cells pass; no output, and the --tmp folder is empty.
TEST_P(Signals, OutOfCoreBuildStopsWithNoOutputOrTemporaryFiles) {
  const fs::path tmp = out_ / "tmp";
  fs::create_directories(tmp);
  const std::string target = out("big.fch");
  Child child({"build", bigMesh(), "-o", target, "--memory", "64M", "--tmp", tmp.string()});
  interruptAfter(child, 1.0);
  EXPECT_TRUE(listing(tmp).empty()) << ::testing::PrintToString(listing(tmp));
  fs::remove_all(tmp);
  expectNothingLeft();
}

// tiles: the signal stops the workers between tiles; no tileset, and no temporary folder beside it.
// A million faces in tiles of 512: seconds of tiling, a second of building.
TEST_P(Signals, TilesStopWithNoOutput) {
  const std::string mesh = (inputs_ / "grid1m.ply").string(), file = (inputs_ / "grid1m.fch").string();
  if (!fs::exists(file)) {
    ASSERT_EQ(runChild({"gen", "grid", "-n", "1M", "-o", mesh}).exitCode, 0);
    ASSERT_EQ(runChild({"build", mesh, "-o", file}).exitCode, 0);
  }
  Child child({"tiles", file, "-o", out("big_tiles"), "--tile-faces", "512", "--threads", "1"});
  interruptAfter(child, 0.3);
  expectNothingLeft();
}

// gen does not poll: the signal thread gives it the grace time, then removes its temporary
// file and exits. If it completes within the grace time its output is complete and it exits 0
// (the contract: exit 0 if and only if the outputs are complete).
TEST_P(Signals, GenerateStopsWithNoOutputOrCompletes) {
  const std::string target = out("big.ply");
  Child child({"gen", "terrain", "-n", "8M", "--shuffle-vertices", "--shuffle-faces", "-o", target});
  ASSERT_TRUE(child.started());
  // Writing has started once the temporary file exists.
  while (child.running() && listing(out_).empty()) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  child.signal(GetParam());
  const ChildResult result = child.wait();
  if (result.exitCode == 0) {
    std::printf("[ note ] gen completed within the grace time\n");
    EXPECT_EQ(listing(out_), std::vector<std::string>{"big.ply"});
    const ChildResult stats = runChild({"stats", target});
    EXPECT_EQ(stats.exitCode, 0) << stats.output;
    fs::remove(target);
  } else {
    EXPECT_EQ(result.exitCode, 128 + GetParam()) << result.output;
    EXPECT_EQ(result.output, message());
  }
  expectNothingLeft();
}

INSTANTIATE_TEST_SUITE_P(IntAndTerm, Signals, ::testing::Values(SIGINT, SIGTERM),
                         [](const auto& info) { return info.param == SIGINT ? "SIGINT" : "SIGTERM"; });

TEST(Options, ThreadsOptionIsChecked) {
  const auto result = test::runCli("build --threads 9 x.ply");
  EXPECT_EQ(result.exitCode, 2);
  EXPECT_EQ(result.out, "facetree: --threads must be 0 (all cores) to 8 (see facetree build --help)\n");
}

}  // namespace
}  // namespace facetree
