// cli_test: the octovk program run as a user runs it. Its .bt / .ot files must be byte-identical
// to OctoMap's graph2tree on the same input and parameters, and bad input must give one error
// line, a non-zero exit code and no file.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <octomap/AbstractOcTree.h>
#include <octomap/OcTree.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cli_support.hpp"
#include "test_support.hpp"

namespace octovk::test {
namespace {

namespace fs = std::filesystem;

const std::string kSphericalGraph = OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR) + "/spherical_scan.graph";
const std::string kFr079Dir = OCTOVK_PATH(OCTOVK_SHARED_DATA_DIR) + "/fr079-2d";

// Node count of an OctoMap file, for a readable failure message.
std::string describeTree(const fs::path& path) {
  std::ifstream in(path, std::ios_base::binary);
  if (!in) return "unreadable";
  if (path.extension() == ".bt") {
    octomap::OcTree tree(0.1);
    if (!tree.readBinary(in)) return "unreadable .bt";
    return std::to_string(tree.size()) + " nodes at " + std::to_string(tree.getResolution());
  }
  std::unique_ptr<octomap::AbstractOcTree> tree(octomap::AbstractOcTree::read(in));
  if (!tree) return "unreadable .ot";
  return std::to_string(tree->size()) + " nodes at " + std::to_string(tree->getResolution());
}

::testing::AssertionResult sameBytes(const fs::path& expected, const fs::path& actual) {
  if (!fs::exists(expected)) return ::testing::AssertionFailure() << expected << " is missing";
  if (!fs::exists(actual)) return ::testing::AssertionFailure() << actual << " is missing";
  const std::string a = readFile(expected);
  const std::string b = readFile(actual);
  if (a == b) return ::testing::AssertionSuccess();
  std::size_t first = 0;
  while (first < a.size() && first < b.size() && a[first] == b[first]) ++first;
  return ::testing::AssertionFailure()
         << actual << " differs from " << expected << ": sizes " << b.size() << " vs " << a.size()
         << " bytes, first difference at byte " << first << "; octovk " << describeTree(actual)
         << ", graph2tree " << describeTree(expected);
}

// Gives `graph2tree` and `log2graph` to a test: a failure under CI, a skip elsewhere.
#define REQUIRE_OCTOMAP_TOOLS()                                                           \
  if (!isExecutable(OCTOVK_PATH(OCTOVK_GRAPH2TREE)) ||                                    \
      !isExecutable(OCTOVK_PATH(OCTOVK_LOG2GRAPH))) {                                     \
    if (::octovk::test::runningInCi())                                                    \
      FAIL() << "graph2tree / log2graph missing under CI: apt-get install octomap-tools"; \
    GTEST_SKIP() << "graph2tree / log2graph missing: apt-get install octomap-tools";      \
  }

// Options given to both programs; empty strings leave a default.
struct Params {
  std::string resolution = "0.1";
  std::string max_range;
  bool discretize = false;
  // All four or none (graph2tree sets them in pairs).
  std::string prob_hit, prob_miss, clamping_min, clamping_max;
};

// Test names show the options, not the bytes of Params.
void PrintTo(const Params& p, std::ostream* os) {
  *os << "resolution " << p.resolution;
  if (!p.max_range.empty()) *os << ", max range " << p.max_range;
  if (p.discretize) *os << ", discretize";
  if (!p.prob_hit.empty())
    *os << ", hit " << p.prob_hit << ", miss " << p.prob_miss << ", clamping " << p.clamping_min
        << ".." << p.clamping_max;
}

// Runs octovk and graph2tree with `p` on `graph` and compares both files byte for byte, plus the
// summary's scan and node counts with graph2tree's.
void expectParity(const std::string& graph, const Params& p, const Scratch& scratch,
                  std::size_t expected_scans, const octovk::Context& ctx) {
  const std::string bt = scratch / "octovk.bt";
  const std::string ot = scratch / "octovk.ot";
  const std::string ref = scratch / "graph2tree.bt";  // graph2tree also writes .bt.ot, _ml.ot

  std::vector<std::string> args = {"integrate", graph, "-o", bt, "--output=" + ot};
  std::string g2t = quote(OCTOVK_PATH(OCTOVK_GRAPH2TREE)) + " -i " + quote(graph) + " -o " +
                    quote(ref) + " -res " + p.resolution;
  args.push_back("--resolution=" + p.resolution);
  if (!p.max_range.empty()) {
    args.insert(args.end(), {"--max-range", p.max_range});
    g2t += " -m " + p.max_range;
  }
  if (p.discretize) {
    args.push_back("--discretize");
    g2t += " -discretize";
  }
  if (!p.prob_hit.empty()) {
    args.insert(args.end(), {"--prob-hit", p.prob_hit, "--prob-miss", p.prob_miss, "--clamping-min",
                             p.clamping_min, "--clamping-max", p.clamping_max});
    g2t += " -sensor " + p.prob_miss + " " + p.prob_hit + " -clamping " + p.clamping_min + " " +
           p.clamping_max;
  }

  const RunResult reference = runShell(g2t, scratch.dir());
  ASSERT_EQ(reference.exit_code, 0) << g2t << "\n" << reference.out << reference.err;
  const RunResult mine = runOctovk(args, scratch.dir());
  ASSERT_EQ(mine.exit_code, 0) << mine.out << mine.err;

  EXPECT_TRUE(sameBytes(ref, bt));
  EXPECT_TRUE(sameBytes(ref + ".ot", ot));

  // The summary tells the truth: scan count, and the node count of the full (.ot) tree, which
  // graph2tree prints first as "Tree size: N nodes".
  EXPECT_NE(mine.out.find("scans:         " + std::to_string(expected_scans) + "\n"),
            std::string::npos)
      << mine.out;
  const std::size_t at = reference.out.find("Tree size: ");
  ASSERT_NE(at, std::string::npos) << reference.out;
  const std::string nodes =
      reference.out.substr(at + 11, reference.out.find(' ', at + 11) - at - 11);
  EXPECT_NE(mine.out.find("nodes:         " + nodes + " in memory"), std::string::npos)
      << "graph2tree has " << nodes << " nodes; octovk said:\n"
      << mine.out;
  EXPECT_NE(mine.out.find("wrote:         " + bt + "\n"), std::string::npos) << mine.out;
  EXPECT_NE(mine.out.find("wrote:         " + ot + "\n"), std::string::npos) << mine.out;
  // The program picks the device this process picked (same OCTOVK_DEVICE, same rules).
  EXPECT_NE(mine.out.find("device: " + ctx.device().name), std::string::npos) << mine.out;
  // OctoMap's reader chatter and error lines stay off stderr on success.
  EXPECT_EQ(mine.err.find("error"), std::string::npos) << mine.err;
  EXPECT_EQ(mine.err.find("from binary file"), std::string::npos) << mine.err;
  // Nothing but the outputs and graph2tree's files is left: no temporary file.
  for (const auto& entry : fs::directory_iterator(scratch.dir()))
    EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << entry.path();
}

// The first 200 scans of the FR-079 log as a scan graph, made once per test process.
class Fr079Graph {
 public:
  static const Fr079Graph& get() {
    static Fr079Graph instance;
    return instance;
  }
  const std::string& path() const { return graph_; }
  const std::string& error() const { return error_; }
  ~Fr079Graph() {
    if (!graph_.empty()) fs::remove(graph_);
  }

 private:
  Fr079Graph() {
    const fs::path dir = fs::path(OCTOVK_PATH(OCTOVK_TEST_TMP));
    fs::create_directories(dir);
    // Per-process names: ctest may run several test processes at once.
    const std::string stem = "fr079_200." + std::to_string(::getpid());
    const std::string log = (dir / (stem + ".log")).string();
    const std::string graph = (dir / (stem + ".graph")).string();
    const RunResult made =
        runShell("python3 " + quote(kFr079Dir + "/clf2log.py") + " " +
                     quote(kFr079Dir + "/fr079.clf.bz2") + " " + quote(log) + " 200 && " +
                     quote(OCTOVK_PATH(OCTOVK_LOG2GRAPH)) + " " + quote(log) + " " + quote(graph),
                 dir);
    fs::remove(log);
    if (made.exit_code == 0 && fs::file_size(graph) > 0)
      graph_ = graph;
    else
      error_ = made.out + made.err;
  }
  std::string graph_;
  std::string error_;
};

// Suite names start with "cli" so that `ctest -R cli` selects exactly these tests.

// ---- parity with graph2tree ----

TEST(cliParity, SphericalScanAt10cm) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  REQUIRE_OCTOMAP_TOOLS();
  Scratch scratch;
  expectParity(kSphericalGraph, {.resolution = "0.1"}, scratch, 1, ctx);
}

TEST(cliParity, SphericalScanAt5cm) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  REQUIRE_OCTOMAP_TOOLS();
  Scratch scratch;
  expectParity(kSphericalGraph, {.resolution = "0.05"}, scratch, 1, ctx);
}

TEST(cliParity, SphericalScanMaxRange2) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  REQUIRE_OCTOMAP_TOOLS();
  Scratch scratch;
  expectParity(kSphericalGraph, {.resolution = "0.1", .max_range = "2"}, scratch, 1, ctx);
}

TEST(cliParity, SphericalScanDiscretize) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  REQUIRE_OCTOMAP_TOOLS();
  Scratch scratch;
  expectParity(kSphericalGraph, {.resolution = "0.1", .discretize = true}, scratch, 1, ctx);
}

class cliFr079 : public ::testing::TestWithParam<Params> {};

TEST_P(cliFr079, MatchesGraph2tree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  REQUIRE_OCTOMAP_TOOLS();
  const std::string& graph = Fr079Graph::get().path();
  ASSERT_FALSE(graph.empty()) << "could not make the FR-079 graph with clf2log.py and log2graph: "
                              << Fr079Graph::get().error();
  Scratch scratch;
  expectParity(graph, GetParam(), scratch, 200, ctx);
}

INSTANTIATE_TEST_SUITE_P(Slice200, cliFr079,
                         ::testing::Values(Params{.resolution = "0.1"},
                                           Params{.resolution = "0.05"},
                                           Params{.resolution = "0.1", .max_range = "10"},
                                           Params{.resolution = "0.05", .max_range = "10"},
                                           Params{.resolution = "0.1",
                                                  .prob_hit = "0.8",
                                                  .prob_miss = "0.35",
                                                  .clamping_min = "0.2",
                                                  .clamping_max = "0.95"}),
                         [](const ::testing::TestParamInfo<Params>& info) {
                           std::string name = "Res" + info.param.resolution;
                           if (!info.param.max_range.empty())
                             name += "MaxRange" + info.param.max_range;
                           if (!info.param.prob_hit.empty()) name += "SensorModel";
                           for (char& c : name)
                             if (c == '.') c = '_';
                           return name;
                         });

// ---- bad input: one error line, the right exit code, nothing written ----

// Runs octovk with `args` and expects exit code `exit_code`, one stderr line that starts with
// "octovk: error: " and mentions `mention`, no stdout, and no map or temporary file in scratch.
void expectRejected(const std::vector<std::string>& args, int exit_code, const std::string& mention,
                    const Scratch& scratch) {
  const RunResult r = runOctovk(args, scratch.dir());
  EXPECT_EQ(r.exit_code, exit_code) << r.err;
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_TRUE(r.err.ends_with("\n")) << r.err;
  EXPECT_NE(r.err.find(mention), std::string::npos) << "expected '" << mention << "' in: " << r.err;
  EXPECT_EQ(r.out, "");
  for (const auto& entry : fs::recursive_directory_iterator(scratch.dir())) {
    const std::string name = entry.path().filename().string();
    EXPECT_FALSE(entry.is_regular_file() && (name.ends_with(".bt") || name.ends_with(".ot") ||
                                             name.find(".tmp") != std::string::npos))
        << "left behind: " << entry.path();
  }
}

TEST(cliBadInput, MissingGraphFile) {
  Scratch scratch;
  const std::string missing = scratch / "no_such.graph";
  expectRejected({"integrate", missing, "-o", scratch / "map.bt"}, 2, missing, scratch);
}

TEST(cliBadInput, GraphIsRandomBytes) {
  Scratch scratch;
  const std::string graph = scratch / "random.graph";
  {
    std::mt19937 rng(42);
    std::ofstream out(graph, std::ios_base::binary);
    for (int i = 0; i < 4096; ++i) out.put(static_cast<char>(rng() & 0xFF));
  }
  expectRejected({"integrate", graph, "-o", scratch / "map.bt", "-o", scratch / "map.ot"}, 1,
                 "scan graph", scratch);
}

TEST(cliBadInput, GraphIsTruncated) {
  Scratch scratch;
  const std::string graph = scratch / "truncated.graph";
  const std::string whole = readFile(kSphericalGraph);
  ASSERT_GT(whole.size(), 1000u);
  std::ofstream(graph, std::ios_base::binary) << whole.substr(0, whole.size() / 2);
  expectRejected({"integrate", graph, "-o", scratch / "map.bt"}, 1, "scan graph", scratch);
}

TEST(cliBadInput, UnknownOutputExtension) {
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "map.xyz"}, 2, ".xyz", scratch);
}

TEST(cliBadInput, ResolutionZero) {
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "map.bt", "--resolution", "0"}, 2,
                 "resolution", scratch);
}

TEST(cliBadInput, ResolutionNegative) {
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "map.bt", "--resolution", "-1"}, 2,
                 "resolution", scratch);
}

TEST(cliBadInput, ResolutionNotANumber) {
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "map.bt", "--resolution", "abc"}, 2,
                 "'abc'", scratch);
}

TEST(cliBadInput, MissingOptionValue) {
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "map.bt", "--resolution"}, 2,
                 "--resolution", scratch);
}

TEST(cliBadInput, BadProbability) {
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "map.bt", "--prob-hit", "0.3"}, 2,
                 "--prob-hit", scratch);
}

TEST(cliBadInput, ClampingBoundsReversed) {
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "map.bt", "--clamping-min", "0.9",
                  "--clamping-max", "0.2"},
                 2, "clamping", scratch);
}

TEST(cliBadInput, OutputDirectoryDoesNotExist) {
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "no_such_dir/map.bt"}, 2,
                 "does not exist", scratch);
  EXPECT_FALSE(fs::exists(scratch.dir() / "no_such_dir"));
}

TEST(cliBadInput, OutputIsAnExistingDirectory) {
  // Tests run as root, so a read-only directory would still be writable; a directory in the
  // place of the output file cannot be written by anyone.
  Scratch scratch;
  fs::create_directory(scratch.dir() / "taken.bt");
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "taken.bt"}, 2, "directory",
                 scratch);
  EXPECT_TRUE(fs::is_empty(scratch.dir() / "taken.bt"));
}

TEST(cliBadInput, OutputParentIsAFile) {
  Scratch scratch;
  std::ofstream(scratch / "plain_file") << "x";
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "plain_file/map.bt"}, 2,
                 "not a directory", scratch);
}

TEST(cliBadInput, SecondOutputUnwritable) {
  // The first output is fine: nothing may be written before every output has been checked.
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "good.bt", "-o",
                  scratch / "no_such_dir/map.ot"},
                 2, "does not exist", scratch);
}

TEST(cliBadInput, MissingOutput) {
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph}, 2, "-o", scratch);
}

TEST(cliBadInput, UnknownOption) {
  Scratch scratch;
  expectRejected({"integrate", kSphericalGraph, "-o", scratch / "map.bt", "--bogus"}, 2, "--bogus",
                 scratch);
}

TEST(cliBadInput, UnknownCommandNamesTheKnownOnes) {
  Scratch scratch;
  expectRejected({"frobnicate"}, 2, "integrate", scratch);
  expectRejected({"frobnicate"}, 2, "devices", scratch);
}

TEST(cliBadInput, NoCommand) {
  Scratch scratch;
  expectRejected({}, 2, "integrate", scratch);
}

// ---- outputs that cannot be created: exit 2 before any work, messages name the user's path ----

// A small .bt map written by OctoMap: a 20 x 20 grid of occupied cells above free ones.
std::string writeSmallMap(const Scratch& scratch) {
  octomap::OcTree tree(0.1);
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) {
      const float x = 0.1f * static_cast<float>(i), y = 0.1f * static_cast<float>(j);
      tree.updateNode(octomap::point3d(x, y, 0.05f * static_cast<float>(i % 5)), true);
      tree.updateNode(octomap::point3d(x, y, -0.5f), false);
    }
  const std::string path = scratch / "small.bt";
  EXPECT_TRUE(tree.writeBinary(path));
  return path;
}

// Output paths whose directory exists and passes access(W_OK), so that only creating the file
// shows they cannot be written: a file name longer than any file system allows and, as root
// (as the tests run under CI), a file in /proc.
std::vector<std::string> uncreatableOutputs(const Scratch& scratch, const std::string& ext) {
  std::vector<std::string> paths = {scratch / (std::string(300, 'n') + ext)};
  if (fs::is_directory("/proc/self")) paths.push_back("/proc/octovk-cli-test" + ext);
  return paths;
}

// `args` with an uncreatable output must exit 2 naming it (not a temporary name) before any work:
// the inputs given are corrupt, so any reading would have failed first with exit 1.
void expectOutputRefusedFirst(const std::vector<std::string>& args, const std::string& output,
                              const Scratch& scratch) {
  std::vector<std::string> with_output = args;
  with_output.insert(with_output.end(), {"-o", output});
  SCOPED_TRACE(args.front() + " -o " + output.substr(0, 60));
  expectRejected(with_output, 2, "cannot write '" + output + "'", scratch);
  const RunResult r = runOctovk(with_output, scratch.dir());
  EXPECT_EQ(r.err.find(".tmp"), std::string::npos) << r.err;
  std::error_code ec;  // a name too long is an error here too
  EXPECT_FALSE(fs::exists(output, ec));
}

TEST(cliOutputs, UncreatableOutputIsExit2BeforeAnyWork) {
  Scratch scratch, inputs("cli-inputs");  // the inputs apart: scratch must hold no map after
  const std::string graph = inputs / "corrupt.graph";
  std::ofstream(graph, std::ios_base::binary) << "not a scan graph at all";
  const std::string map = writeSmallMap(inputs);
  const std::string corrupt_map = inputs / "corrupt.bt";
  {
    std::string bytes = readFile(map);
    const std::size_t size_at = bytes.find("\nsize ");
    ASSERT_NE(size_at, std::string::npos);
    bytes.replace(size_at + 1, bytes.find('\n', size_at + 1) - size_at - 1, "size 0");
    std::ofstream(corrupt_map, std::ios_base::binary) << bytes;
  }
  // The corrupt inputs alone fail while working (exit 1): their error must not come first.
  expectRejected({"integrate", graph, "-o", scratch / "map.bt"}, 1, graph, scratch);
  expectRejected({"render", corrupt_map, "-o", scratch / "view.png"}, 1, corrupt_map, scratch);
  for (const std::string& out : uncreatableOutputs(scratch, ".bt"))
    expectOutputRefusedFirst({"integrate", graph}, out, scratch);
  // The second of two outputs: the first is neither written nor left as a temporary file.
  for (const std::string& out : uncreatableOutputs(scratch, ".ot"))
    expectOutputRefusedFirst({"integrate", graph, "-o", scratch / "first.bt"}, out, scratch);
  EXPECT_FALSE(fs::exists(scratch / "first.bt"));
  for (const std::string& out : uncreatableOutputs(scratch, ".png"))
    expectOutputRefusedFirst({"render", corrupt_map}, out, scratch);
  for (const std::string& out : uncreatableOutputs(scratch, ".ply"))
    expectOutputRefusedFirst({"export", corrupt_map}, out, scratch);
  // With a good input too: nothing printed, no device opened.
  for (const std::string& out : uncreatableOutputs(scratch, ".png"))
    expectOutputRefusedFirst({"render", map}, out, scratch);
  for (const std::string& out : uncreatableOutputs(scratch, ".ply"))
    expectOutputRefusedFirst({"export", map}, out, scratch);
}

// Runs octovk with `args` while no file may grow past 512 bytes (ulimit -f 1; SIGXFSZ ignored so
// that the write fails instead): the write of the output fails after the work.
// The limit binds the Vulkan driver too, and Mesa 25's lavapipe backs device memory with memfd
// files: under it the process dies of SIGBUS in the driver (octovk builds of before this test do
// the same). This test is about octovk's own file writes, so its command runs on the system's
// default driver (the Mesa 25 step's VK_DRIVER_FILES / LD_LIBRARY_PATH removed for it alone).
// Only on lavapipe: a GPU driver is not expected to back device memory with files, and there the
// variables are what find the driver and the bundle's libraries (run.sh of scripts/bundle.sh).
// With `default_sigxfsz`, SIGXFSZ keeps its default action (ending the process) instead.
RunResult runWithFileLimit(const std::vector<std::string>& args, const Scratch& scratch, int blocks,
                           bool default_sigxfsz = false) {
  const octovk::Context* context = octovk::test::sharedContext(nullptr);
  const bool lavapipe = context && context->device().name.find("llvmpipe") != std::string::npos;
  std::string command =
      std::string(default_sigxfsz ? "trap - XFSZ; " : "trap '' XFSZ; ") + "ulimit -f " +
      std::to_string(blocks) + "; " +
      (lavapipe ? "env -u VK_DRIVER_FILES -u VK_ICD_FILENAMES -u LD_LIBRARY_PATH " : "") +
      quote(OCTOVK_PATH(OCTOVK_CLI));
  for (const std::string& a : args) command += ' ' + quote(a);
  return runShell(command, scratch.dir());
}

RunResult runWithTinyFileLimit(const std::vector<std::string>& args, const Scratch& scratch,
                               bool default_sigxfsz = false) {
  return runWithFileLimit(args, scratch, 1, default_sigxfsz);
}

class cliFileLimit : public ::testing::TestWithParam<bool> {};

// Without the parameter, SIGXFSZ is ignored by whoever starts octovk; with it, it has its
// default action, which killed the run (exit 153) and left a temporary: octovk ignores it itself.
TEST_P(cliFileLimit, WriteFailuresNameTheUsersPathAndLeaveNothing) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  const bool default_sigxfsz = GetParam();
  Scratch scratch;
  const std::string map = writeSmallMap(scratch);
  struct Case {
    std::vector<std::string> args;
    std::string output;
  };
  for (const Case& c :
       {Case{{"export", map, "-o", scratch / "cells.ply"}, scratch / "cells.ply"},
        Case{{"render", map, "-o", scratch / "view.png"}, scratch / "view.png"},
        Case{{"integrate", kSphericalGraph, "-q", "-o", scratch / "out.bt"}, scratch / "out.bt"}}) {
    SCOPED_TRACE(c.args.front());
    const RunResult r = runWithTinyFileLimit(c.args, scratch, default_sigxfsz);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find("'" + c.output + "'"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find(".tmp"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(c.output));
    for (const auto& entry : fs::directory_iterator(scratch.dir()))
      EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos)
          << "left behind: " << entry.path();
  }
  // Without the limit the same commands work.
  const RunResult ok = runOctovk({"export", map, "-o", scratch / "cells.ply"}, scratch.dir());
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_GT(fs::file_size(scratch / "cells.ply"), 512u);
}

INSTANTIATE_TEST_SUITE_P(Sigxfsz, cliFileLimit, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& info) {
                           return info.param ? std::string("Default") : std::string("Ignored");
                         });

TEST(cliOutputs, EveryNameTheDirectoryTakesCanBeWritten) {
  // Names of up to NAME_MAX bytes (255 here) were refused as "File name too long": their
  // temporaries, ".NAME.octovk.tmp-PID.EXT", were longer.
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  const long name_max = ::pathconf(scratch.dir().c_str(), _PC_NAME_MAX);
  ASSERT_GT(name_max, 40);
  const std::size_t longest = static_cast<std::size_t>(name_max);
  // Two names that differ only at their end, where a cut temporary name would lose them.
  const std::string bt = scratch / (std::string(longest - 4, 'n') + "a.bt");
  const std::string ot = scratch / (std::string(longest - 4, 'n') + "b.ot");
  const std::string mid = scratch / (std::string(longest - 20, 'm') + ".bt");
  const RunResult r =
      runOctovk({"integrate", kSphericalGraph, "-q", "-o", bt, "-o", ot}, scratch.dir());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_GT(fs::file_size(bt), 0u);
  EXPECT_GT(fs::file_size(ot), fs::file_size(bt));
  const RunResult m = runOctovk({"integrate", kSphericalGraph, "-q", "-o", mid}, scratch.dir());
  EXPECT_EQ(m.exit_code, 0) << m.err;
  EXPECT_EQ(readFile(mid), readFile(bt));
  EXPECT_EQ(temporariesIn(scratch.dir()), std::vector<std::string>{});
  // One byte more than the directory takes is still refused, before any work, naming it.
  const std::string too_long = scratch / (std::string(longest - 2, 'n') + ".bt");
  const RunResult refused =
      runOctovk({"integrate", kSphericalGraph, "-q", "-o", too_long}, scratch.dir());
  EXPECT_EQ(refused.exit_code, 2) << refused.err;
  EXPECT_NE(refused.err.find("cannot write '" + too_long + "'"), std::string::npos) << refused.err;
}

// ---- nothing lost on any failure: all-or-nothing outputs, signals, stale temporaries ----

// Distinct bytes for a file that a failed run must leave exactly as it was.
std::string oldContent(const std::string& name) {
  return "the user's previous " + name + ", which a failed run must keep\n" + std::string(100, 'x');
}

TEST(cliNothingLost, SecondOutputFailingLeavesEveryOldFileByteForByte) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  // The files of a run without a limit: the .bt is small, the .ot some ten times larger.
  const RunResult ref = runOctovk(
      {"integrate", kSphericalGraph, "-q", "-o", scratch / "ref.bt", "-o", scratch / "ref.ot"},
      scratch.dir());
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  const std::string ref_bt = readFile(scratch / "ref.bt"), ref_ot = readFile(scratch / "ref.ot");
  // 8 blocks of 512 bytes (dash) or 1024 (bash): the .bt fits either way, the .ot does not.
  constexpr int kBlocks = 8;
  ASSERT_LE(ref_bt.size(), kBlocks * 512u);
  ASSERT_GT(ref_ot.size(), kBlocks * 1024u);

  const std::string bt = scratch / "a.bt", ot = scratch / "b.ot";
  // Both orders: the failing write first, and second (once the .bt is complete, which the old
  // code had renamed into place and then deleted).
  for (const std::vector<std::string>& order : {std::vector<std::string>{bt, ot}, {ot, bt}}) {
    SCOPED_TRACE("outputs " + order[0] + ", " + order[1]);
    std::ofstream(bt, std::ios_base::binary) << oldContent("a.bt");
    std::ofstream(ot, std::ios_base::binary) << oldContent("b.ot");
    const RunResult r = runWithFileLimit(
        {"integrate", kSphericalGraph, "-q", "-o", order[0], "-o", order[1]}, scratch, kBlocks);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find("'" + ot + "'"), std::string::npos) << r.err;  // the .bt was written
    EXPECT_EQ(r.err.find(".tmp"), std::string::npos) << r.err;
    EXPECT_EQ(readFile(bt), oldContent("a.bt"));
    EXPECT_EQ(readFile(ot), oldContent("b.ot"));
    EXPECT_EQ(temporariesIn(scratch.dir()), std::vector<std::string>{});
  }
  // With no files there before, none after.
  fs::remove(bt);
  fs::remove(ot);
  const RunResult fresh =
      runWithFileLimit({"integrate", kSphericalGraph, "-q", "-o", bt, "-o", ot}, scratch, kBlocks);
  EXPECT_EQ(fresh.exit_code, 1) << fresh.err;
  EXPECT_FALSE(fs::exists(bt));
  EXPECT_FALSE(fs::exists(ot));
  EXPECT_EQ(temporariesIn(scratch.dir()), std::vector<std::string>{});

  // Without the limit the same run replaces both old files with the complete new ones.
  std::ofstream(bt, std::ios_base::binary) << oldContent("a.bt");
  std::ofstream(ot, std::ios_base::binary) << oldContent("b.ot");
  const RunResult ok =
      runOctovk({"integrate", kSphericalGraph, "-q", "-o", bt, "-o", ot}, scratch.dir());
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_EQ(readFile(bt), ref_bt);
  EXPECT_EQ(readFile(ot), ref_ot);
  EXPECT_EQ(temporariesIn(scratch.dir()), std::vector<std::string>{});
}

// The spherical scan `copies` times over: a run long enough to be interrupted.
std::string writeLongGraph(const Scratch& scratch, std::size_t copies) {
  const std::vector<octovk::GraphScan> scans = octovk::readScanGraph(kSphericalGraph);
  const std::string path = scratch / "long.graph";
  // OctoMap's writer reports every scan on stderr: kept out of the test log.
  std::fflush(stderr);
  const int saved = ::dup(STDERR_FILENO);
  const int null_fd = ::open("/dev/null", O_WRONLY);
  ::dup2(null_fd, STDERR_FILENO);
  ::close(null_fd);
  octovk::writeScanGraph(path, copies, [&](std::size_t) { return scans.front(); });
  std::fflush(stderr);
  ::dup2(saved, STDERR_FILENO);
  ::close(saved);
  return path;
}

TEST(cliNothingLost, SignalsRemoveTheTemporariesAndEndTheRunBySignal) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch, inputs("cli-inputs");  // the graph apart: scratch holds only the outputs
  const std::string graph = writeLongGraph(inputs, 64);
  const std::string bt = scratch / "a.bt", ot = scratch / "b.ot";
  // Each signal once the temporaries exist; some also once the device is open, when the
  // driver's threads run too (a signal must not end the run through one of them).
  for (const auto& [sig, on_device] : std::vector<std::pair<int, bool>>{
           {SIGTERM, false}, {SIGTERM, true}, {SIGINT, true}, {SIGHUP, false}}) {
    SCOPED_TRACE("signal " + std::to_string(sig) + (on_device ? " at work" : " at the start"));
    std::ofstream(bt, std::ios_base::binary) << oldContent("a.bt");
    fs::remove(ot);
    OctovkProcess run({"integrate", graph, "-q", "-r", "0.05", "-o", bt, "-o", ot}, inputs.dir());
    ASSERT_TRUE(run.started());
    // 64 scans take a second or more on lavapipe; the signal follows within milliseconds.
    const bool claimed = pollUntil([&] { return temporariesIn(scratch.dir()).size() == 2; },
                                   std::chrono::seconds(60));
    EXPECT_TRUE(claimed) << "the run made no temporaries";
    if (on_device) {
      const bool working =
          pollUntil([&] { return readFile(inputs.dir() / "stdout.txt").find("device: ") == 0; },
                    std::chrono::seconds(60));
      EXPECT_TRUE(working) << "the run printed no device line";
    }
    run.signal(sig);
    const RunResult r = run.wait();
    EXPECT_EQ(r.exit_code, 128 + sig) << r.out << r.err;
    EXPECT_EQ(r.out.find("scans:"), std::string::npos) << "the run ended before the signal";
    EXPECT_EQ(readFile(bt), oldContent("a.bt"));
    EXPECT_FALSE(fs::exists(ot));
    EXPECT_EQ(temporariesIn(scratch.dir()), std::vector<std::string>{});
  }
}

TEST(cliNothingLost, TemporariesOfDeadRunsAreRemovedByTheNextRun) {
  // No device needed: the temporaries are claimed before the (corrupt) graph is read.
  Scratch scratch, inputs("cli-inputs");
  const std::string graph = inputs / "corrupt.graph";
  std::ofstream(graph, std::ios_base::binary) << "not a scan graph at all";
  // A process id that is surely gone: a child that has ended and been waited for.
  const pid_t dead = ::fork();
  if (dead == 0) ::_exit(0);
  ASSERT_GT(dead, 0);
  ::waitpid(dead, nullptr, 0);
  const std::string dead_id = std::to_string(dead), live_id = std::to_string(::getpid());
  const auto make = [&](const std::string& name, const std::string& content) {
    std::ofstream(scratch / name, std::ios_base::binary) << content;
  };
  make("out.bt", oldContent("out.bt"));
  make(".out.bt.octovk.tmp-" + dead_id + ".bt", "partial map of a killed run");
  make(".out.bt.octovk.tmp-" + dead_id + ".old", "backup of a killed run, out.bt in place");
  make(".out.ot.octovk.tmp-" + dead_id + ".ot", "partial map of a killed run");
  make(".out.bt.octovk.tmp-" + live_id + ".bt", "a running process's temporary: kept");
  make(".out.bt.octovk.tmp-" + dead_id + ".txt", "not a name octovk makes: kept");
  make(".gone.bt.octovk.tmp-" + dead_id + ".old", oldContent("gone.bt"));  // output missing

  const RunResult r = runOctovk({"integrate", graph, "-o", scratch / "out.bt", "-o",
                                 scratch / "out.ot", "-o", scratch / "gone.bt"},
                                scratch.dir());
  EXPECT_EQ(r.exit_code, 1) << r.err;  // the corrupt graph, after the claim
  EXPECT_NE(r.err.find(graph), std::string::npos) << r.err;
  std::vector<std::string> kept = {".out.bt.octovk.tmp-" + dead_id + ".txt",
                                   ".out.bt.octovk.tmp-" + live_id + ".bt"};
  std::sort(kept.begin(), kept.end());
  EXPECT_EQ(temporariesIn(scratch.dir()), kept);
  EXPECT_EQ(readFile(scratch / "out.bt"), oldContent("out.bt"));
  EXPECT_FALSE(fs::exists(scratch / "out.ot"));
  // A backup whose output is missing (killed between moving it aside and the rename) goes back.
  EXPECT_EQ(readFile(scratch / "gone.bt"), oldContent("gone.bt"));
}

TEST(cliNothingLost, ASymlinkedOutputKeepsItsLinkAndAReplacedFileItsMode) {
  // The link was replaced by a regular file, and a read-only (0444) file came back 0644.
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  const RunResult ref = runOctovk(
      {"integrate", kSphericalGraph, "-q", "-o", scratch / "ref.bt", "-o", scratch / "ref.ot"},
      scratch.dir());
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  fs::create_directory(scratch.dir() / "maps");
  const std::string real = scratch / "maps/real.bt", link = scratch / "link.bt";
  std::ofstream(real, std::ios_base::binary) << oldContent("real.bt");
  fs::create_symlink("maps/real.bt", link);  // relative: to the link's directory
  const std::string read_only = scratch / "read_only.ot";
  std::ofstream(read_only, std::ios_base::binary) << oldContent("read_only.ot");
  fs::permissions(read_only,
                  fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  const std::string dangling = scratch / "dangling.bt";  // to a file not there yet
  fs::create_symlink("maps/made.bt", dangling);

  const RunResult r =
      runOctovk({"integrate", kSphericalGraph, "-q", "-o", link, "-o", read_only}, scratch.dir());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(fs::read_symlink(link), fs::path("maps/real.bt"));
  EXPECT_EQ(readFile(real), readFile(scratch / "ref.bt"));
  EXPECT_EQ(readFile(read_only), readFile(scratch / "ref.ot"));
  EXPECT_EQ(fs::status(read_only).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  const RunResult made =
      runOctovk({"integrate", kSphericalGraph, "-q", "-o", dangling}, scratch.dir());
  EXPECT_EQ(made.exit_code, 0) << made.err;
  EXPECT_TRUE(fs::is_symlink(dangling));
  EXPECT_EQ(readFile(scratch / "maps/made.bt"), readFile(scratch / "ref.bt"));
  EXPECT_EQ(temporariesIn(scratch.dir()), std::vector<std::string>{});
  EXPECT_EQ(temporariesIn(scratch.dir() / "maps"), std::vector<std::string>{});
}

TEST(cliNothingLost, RunsWritingTheSameOutputsCommitInTurn) {
  // Three runs writing one -o set at once left it mixed (a .bt of one run beside the .ot of
  // another) in 2 of 25 trials: their renames interleaved. A commit now holds an exclusive flock
  // on each output's directory: while this test holds it, a run's complete set must wait.
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch, inputs("cli-inputs");
  const RunResult ref = runOctovk(
      {"integrate", kSphericalGraph, "-q", "-o", inputs / "ref.bt", "-o", inputs / "ref.ot"},
      inputs.dir());
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  const std::string ref_bt = readFile(inputs / "ref.bt"), ref_ot = readFile(inputs / "ref.ot");
  const std::string bt = scratch / "a.bt", ot = scratch / "b.ot";
  const int dir_fd = ::open(scratch.dir().c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  ASSERT_GE(dir_fd, 0);
  ASSERT_EQ(::flock(dir_fd, LOCK_EX), 0);
  OctovkProcess run({"integrate", kSphericalGraph, "-q", "-o", bt, "-o", ot}, inputs.dir());
  ASSERT_TRUE(run.started());
  // Both temporaries complete (or, without the lock, the outputs already in place).
  const auto written = [&] {
    if (fs::exists(bt) || fs::exists(ot)) return true;
    std::size_t complete = 0;
    for (const std::string& name : temporariesIn(scratch.dir())) {
      std::error_code ec;
      const std::uintmax_t size = fs::file_size(scratch.dir() / name, ec);
      if (!ec && ((name.ends_with(".bt") && size == ref_bt.size()) ||
                  (name.ends_with(".ot") && size == ref_ot.size())))
        ++complete;
    }
    return complete == 2;
  };
  EXPECT_TRUE(pollUntil(written, std::chrono::seconds(60)));
  ::usleep(300 * 1000);  // time enough to rename two files, were the lock not honoured
  EXPECT_FALSE(fs::exists(bt)) << "committed while another process held the directory's lock";
  EXPECT_FALSE(fs::exists(ot)) << "committed while another process held the directory's lock";
  ::flock(dir_fd, LOCK_UN);
  ::close(dir_fd);
  const RunResult r = run.wait();
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(readFile(bt), ref_bt);
  EXPECT_EQ(readFile(ot), ref_ot);
  EXPECT_EQ(temporariesIn(scratch.dir()), std::vector<std::string>{});
}

TEST(cliEdit, AKeepBoxLargerThanTheMapKeepsAllOfItAndSaysSo) {
  // A --keep-box with a corner outside the key range deleted the whole map with exit 0 (OctoMap's
  // iterator visits nothing for it); it is clamped as export --box is, and the summary says so.
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  const std::string map = scratch / "map.bt";
  ASSERT_EQ(runOctovk({"integrate", kSphericalGraph, "-q", "-o", map}, scratch.dir()).exit_code, 0);
  const std::string kept = scratch / "kept.bt";
  const RunResult r = runOctovk(
      {"edit", map, "--keep-box", "-1e6", "-1e6", "-1e6", "1e6", "1e6", "1e6", "-o", kept},
      scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::size_t before = 0, after = 0;
  const std::size_t at = r.out.find("nodes:   ");
  ASSERT_NE(at, std::string::npos) << r.out;
  ASSERT_EQ(std::sscanf(r.out.c_str() + at, "nodes: %zu before, %zu after", &before, &after), 2)
      << r.out;
  EXPECT_GT(before, 1000u) << r.out;
  EXPECT_EQ(after, before) << r.out;
  // The box used is the domain at 0.1 m (32767.5 cells each way), and the one given is named.
  EXPECT_NE(r.out.find("kept:    min (-3276.75, -3276.75, -3276.75) max (3276.75, 3276.75, "
                       "3276.75) m (the box given, min (-1e+06, -1e+06, -1e+06) max (1e+06, "
                       "1e+06, 1e+06), clamped"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(readFile(kept), readFile(map));
  // A --clear-box as large clears every leaf: none is left occupied.
  const std::string cleared = scratch / "cleared.bt";
  const RunResult c = runOctovk(
      {"edit", map, "--clear-box", "-1e6", "-1e6", "-1e6", "1e6", "1e6", "1e6", "-o", cleared},
      scratch.dir());
  ASSERT_EQ(c.exit_code, 0) << c.err;
  octomap::OcTree tree(0.1);
  ASSERT_TRUE(tree.readBinary(cleared));
  std::size_t occupied = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it)
    if (tree.isNodeOccupied(*it)) ++occupied;
  EXPECT_EQ(occupied, 0u);
  EXPECT_GT(tree.getNumLeafNodes(), 0u);
}

// Runs `args`, which must be refused with exit 2 and one error line naming `mention`, leaving
// `kept` byte for byte as it was and no temporary in `dir`.
void expectRefusedKeeping(const std::vector<std::string>& args, const std::string& mention,
                          const std::string& kept, const fs::path& dir) {
  SCOPED_TRACE(args.front() + " ... " + mention);
  const std::string before = readFile(kept);
  const RunResult r = runOctovk(args, dir);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("'" + mention + "'"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(readFile(kept), before);
  EXPECT_EQ(temporariesIn(dir), std::vector<std::string>{});
}

TEST(cliNothingLost, AnOutputThatIsAnInputOrAnotherOutputIsRefused) {
  Scratch scratch;
  // A scan graph named like a map: the same name as input and output.
  const std::string same = scratch / "same.bt";
  fs::copy_file(kSphericalGraph, same);
  expectRefusedKeeping({"integrate", same, "-o", same}, same, same, scratch.dir());
  // Through a symlink and a hard link to the input.
  const std::string link = scratch / "link.bt", hard = scratch / "hard.ot";
  fs::create_symlink(same, link);
  fs::create_hard_link(same, hard);
  expectRefusedKeeping({"integrate", same, "-o", link}, link, same, scratch.dir());
  expectRefusedKeeping({"integrate", same, "-o", scratch / "new.bt", "-o", hard}, hard, same,
                       scratch.dir());
  EXPECT_FALSE(fs::exists(scratch / "new.bt"));
  // Two outputs that are one file: spelt differently, or a symlink to the other.
  const std::string map = writeSmallMap(scratch);  // small.bt
  const std::string alias = scratch / "alias.ot";
  fs::create_symlink(map, alias);
  expectRefusedKeeping({"integrate", kSphericalGraph, "-o", map, "-o", alias}, alias, map,
                       scratch.dir());
  expectRefusedKeeping(
      {"integrate", kSphericalGraph, "-o", map, "-o", (scratch.dir() / "." / "small.bt").string()},
      (scratch.dir() / "." / "small.bt").string(), map, scratch.dir());
  // render and export: an output that is a symlink to the map read.
  const std::string view = scratch / "view.png", cells = scratch / "cells.ply";
  fs::create_symlink(map, view);
  fs::create_symlink(map, cells);
  expectRefusedKeeping({"render", map, "-o", view}, view, map, scratch.dir());
  expectRefusedKeeping({"export", map, "-o", cells}, cells, map, scratch.dir());
}

TEST(cliNothingLost, FifosAreRefusedWithoutBlocking) {
  Scratch scratch;
  const std::string fifo_map = scratch / "fifo.bt", fifo_graph = scratch / "fifo.graph",
                    fifo_ply = scratch / "fifo.ply";
  for (const std::string& fifo : {fifo_map, fifo_graph, fifo_ply})
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0) << fifo;
  const std::string map = writeSmallMap(scratch);
  for (const auto& [args, mention] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"info", fifo_map}, fifo_map},
           {{"render", fifo_map, "-o", scratch / "view.png"}, fifo_map},
           {{"export", fifo_map, "-o", scratch / "cells.ply"}, fifo_map},
           {{"integrate", fifo_graph, "-o", scratch / "map.bt"}, fifo_graph},
           // As outputs: the rename would replace the FIFO rather than write into it.
           {{"integrate", kSphericalGraph, "-o", fifo_map}, fifo_map},
           {{"export", map, "-o", fifo_ply}, fifo_ply}}) {
    SCOPED_TRACE(args.front() + " " + args[1]);
    // Under `timeout`: a run blocked on the FIFO would end with 124, not hang the test.
    std::string command = "timeout 60 " + quote(OCTOVK_PATH(OCTOVK_CLI));
    for (const std::string& a : args) command += ' ' + quote(a);
    const auto start = std::chrono::steady_clock::now();
    const RunResult r = runShell(command, scratch.dir());
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(30));
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find("'" + mention + "'"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("not a regular file"), std::string::npos) << r.err;
    EXPECT_TRUE(fs::is_fifo(mention));
  }
  EXPECT_EQ(temporariesIn(scratch.dir()), std::vector<std::string>{});
}

// Runs octovk with `args` and its stdout redirected by `redirect` (">/dev/full", ">&-").
RunResult runWithStdout(const std::vector<std::string>& args, const std::string& redirect,
                        const Scratch& scratch) {
  std::string command = "(" + quote(OCTOVK_PATH(OCTOVK_CLI));
  for (const std::string& a : args) command += ' ' + quote(a);
  return runShell(command + ' ' + redirect + ")", scratch.dir());
}

void expectStdoutFailure(const RunResult& r) {
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_EQ(r.err.rfind("octovk: error: cannot write to standard output", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST(cliNothingLost, AFullOrClosedStdoutIsAFailure) {
  Scratch scratch;
  ASSERT_TRUE(fs::exists("/dev/full"));
  for (const char* redirect : {">/dev/full", ">&-"}) {
    SCOPED_TRACE(redirect);
    expectStdoutFailure(runWithStdout({"--help"}, redirect, scratch));
    expectStdoutFailure(runWithStdout({"integrate", "--help"}, redirect, scratch));
  }
  EXPECT_EQ(runWithStdout({"--help"}, ">/dev/null", scratch).exit_code, 0);
}

TEST(cliNothingLost, AFullOrClosedStdoutFailsAWorkingRunToo) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  const std::string map = writeSmallMap(scratch);
  for (const char* redirect : {">/dev/full", ">&-"}) {
    SCOPED_TRACE(redirect);
    expectStdoutFailure(runWithStdout({"info", map}, redirect, scratch));
    expectStdoutFailure(runWithStdout({"devices"}, redirect, scratch));
  }
  EXPECT_EQ(runWithStdout({"info", map}, ">/dev/null", scratch).exit_code, 0);
  // With stdout closed the map is still the map: no file opened later takes stdout's number.
  const RunResult ref =
      runOctovk({"integrate", kSphericalGraph, "-q", "-o", scratch / "ref.bt"}, scratch.dir());
  ASSERT_EQ(ref.exit_code, 0) << ref.err;
  expectStdoutFailure(runWithStdout(
      {"integrate", kSphericalGraph, "-q", "-o", scratch / "closed.bt"}, ">&-", scratch));
  EXPECT_EQ(readFile(scratch / "closed.bt"), readFile(scratch / "ref.bt"));
}

TEST(cliOutputs, ReadingErrorsNameTheFileAndTheFault) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch;
  const std::string map = writeSmallMap(scratch);
  const std::string bytes = readFile(map);
  const auto variant = [&](const std::string& name, const std::string& from,
                           const std::string& to) {
    std::string edited = bytes;
    const std::size_t at = edited.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    edited.replace(at, from.size(), to);
    const std::string path = scratch / name;
    std::ofstream(path, std::ios_base::binary) << edited;
    return path;
  };
  const std::string color = variant("foo.bt", "id OcTree", "id Foo");
  const std::string two_res = variant("two_res.bt", "res 0.1", "res 0.2 0.3");
  const std::string deep = scratch / "deep.bt";
  std::ofstream(deep, std::ios_base::binary)
      << bytes.substr(0, bytes.find("\ndata\n") + 6) << std::string(200000, '\xff');
  for (const auto& [path, fault] : std::vector<std::pair<std::string, std::string>>{
           {color, "'Foo'; octovk reads OcTree, ColorOcTree and OcTreeStamped"},
           {two_res, "must be 'res' and one value"},
           {deep, "deeper than a tree's 16 levels"}}) {
    for (const std::vector<std::string>& args :
         {std::vector<std::string>{"info", path}, {"export", path, "-o", scratch / "c.ply"}}) {
      const RunResult r = runOctovk(args, scratch.dir());
      EXPECT_EQ(r.exit_code, 1) << r.err;
      EXPECT_NE(r.err.find("'" + path + "'"), std::string::npos) << r.err;
      EXPECT_NE(r.err.find(fault), std::string::npos) << r.err;
      EXPECT_FALSE(fs::exists(scratch / "c.ply"));
    }
  }
}

TEST(cliOutputs, HelpDescribesExitCode2ForUncreatableOutputs) {
  Scratch scratch;
  // Exit codes are described once, in 'octovk help environment'; each command points there.
  const RunResult r = runOctovk({"help", "environment"}, scratch.dir());
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("output file that cannot be created"), std::string::npos) << r.out;
  const RunResult command = runOctovk({"export", "--help"}, scratch.dir());
  EXPECT_NE(command.out.find("octovk help environment"), std::string::npos) << command.out;
}

// ---- help and devices ----

void expectFullIntegrateHelp(const std::string& text) {
  for (const char* word :
       {"integrate", "-o", "--output", "--resolution", "--max-range", "--prob-hit", "--prob-miss",
        "--clamping-min", "--clamping-max", "--discretize", "--quiet", "--help", ".bt", ".ot",
        "OCTOVK_DEVICE", "Exit codes", "graph2tree"})
    EXPECT_NE(text.find(word), std::string::npos) << "help lacks '" << word << "'";
  // The defaults (OctoMap's), and the unlimited max range.
  for (const std::string& value : {std::string("default: 0.1)"), std::string("default: 0.7)"),
                                   std::string("default: 0.4)"), std::string("default: 0.1192)"),
                                   std::string("default: 0.971)"), std::string("default: -1)")})
    EXPECT_NE(text.find(value), std::string::npos) << "help lacks '" << value << "'";
}

// The top-level help is short (issue 30: it was 152 lines, then 134 with integrate's whole help):
// what octovk is, the commands one line each, examples, and where to read on. What it says must
// be true: it lists exactly the commands the program has (the ones its error on an unknown
// command names), each with a help of its own, and its examples parse.
TEST(cliHelp, TopLevelHelpListsEveryCommandTruly) {
  Scratch scratch;
  const RunResult unknown = runOctovk({"frobnicate"}, scratch.dir());
  const std::size_t names_at = unknown.err.find("commands: ");
  ASSERT_NE(names_at, std::string::npos) << unknown.err;
  std::set<std::string> programs;  // "integrate, convert, ..., help, version (see ...)"
  std::istringstream names(unknown.err.substr(names_at + 10));
  for (std::string name; names >> name;) {
    const bool last = name.back() != ',';
    if (!last) name.pop_back();
    programs.insert(name);
    if (last) break;
  }
  EXPECT_GE(programs.size(), 10u) << unknown.err;
  for (const char* spelling : {"--help", "help", "-h"}) {
    const RunResult r = runOctovk({spelling}, scratch.dir());
    EXPECT_EQ(r.exit_code, 0);
    EXPECT_EQ(r.err, "");
    const std::size_t at = r.out.find("\nCommands:\n");
    ASSERT_NE(at, std::string::npos) << r.out;
    std::set<std::string> listed;
    std::istringstream lines(r.out.substr(at + 11));
    for (std::string line; std::getline(lines, line) && !line.empty();) {
      std::istringstream words(line);
      std::string name, first_word;
      words >> name >> first_word;
      EXPECT_FALSE(first_word.empty()) << "no summary: " << line;
      listed.insert(name);
    }
    EXPECT_EQ(listed, programs) << r.out;
    for (const std::string& name : listed) {
      if (name == "help" || name == "version") continue;
      const RunResult own = runOctovk({name, "--help"}, scratch.dir());
      EXPECT_EQ(own.exit_code, 0) << name;
      EXPECT_EQ(own.out.rfind("octovk " + name, 0), 0u) << own.out;
    }
    for (const char* word : {"OctoMap", "Examples:", "octovk integrate scans.graph", "--version",
                             "octovk COMMAND --help", "octovk help environment"})
      EXPECT_NE(r.out.find(word), std::string::npos) << spelling << " lacks '" << word << "'";
    EXPECT_EQ(r.out.find("OCTOVK_CACHE_DIR"), std::string::npos) << spelling;
  }
}

TEST(cliHelp, HelpCommandAndIntegrateHelp) {
  Scratch scratch;
  for (const std::vector<std::string>& args : {std::vector<std::string>{"help", "integrate"},
                                               {"integrate", "--help"},
                                               {"integrate", "-h"}}) {
    const RunResult r = runOctovk(args, scratch.dir());
    EXPECT_EQ(r.exit_code, 0) << args.front();
    EXPECT_EQ(r.err, "");
    expectFullIntegrateHelp(r.out);
  }
}

TEST(cliDevices, ListsTheDeviceInUse) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch;
  const RunResult r = runOctovk({"devices"}, scratch.dir());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(ctx.device().name), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("selected: "), std::string::npos) << r.out;
}

TEST(cliDevices, UnmatchedSelectorIsOneErrorLine) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;  // the selector below must fail on a machine that has a device
  Scratch scratch;
  const RunResult r =
      runShell("OCTOVK_DEVICE=no-such-device-xyz " + quote(OCTOVK_PATH(OCTOVK_CLI)) +
                   " integrate " + quote(kSphericalGraph) + " -o " + quote(scratch / "map.bt"),
               scratch.dir());
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("OCTOVK_DEVICE"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_FALSE(fs::exists(scratch / "map.bt"));
}

}  // namespace
}  // namespace octovk::test
