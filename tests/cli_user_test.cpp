// cli_user_test: what a new user of the octovk program meets first: --version, OctoMap's option
// spellings, a map given where a scan graph belongs, an empty graph, and integrate's summary.
// Small inputs only: each test runs in well under a second on lavapipe.
#include <gtest/gtest.h>
#include <octomap/AbstractOcTree.h>
#include <octomap/OcTree.h>
#include <octomap/ScanGraph.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cli_support.hpp"

namespace octovk::test {
namespace {

namespace fs = std::filesystem;

// One error line, exit `exit_code`, naming each of `mentions`, and no map left behind.
void expectOneError(const RunResult& r, int exit_code, const std::vector<std::string>& mentions,
                    const Scratch& scratch) {
  expectOneErrorLine(r, exit_code, mentions);
  EXPECT_EQ(r.out, "");
  for (const auto& entry : fs::directory_iterator(scratch.dir())) {
    const std::string name = entry.path().filename().string();
    EXPECT_FALSE(name.starts_with("out.") || name.find(".tmp") != std::string::npos)
        << "left behind: " << name;
  }
}

// A scan graph of `scans` scans of `points` points each, written by OctoMap.
std::string writeGraph(const Scratch& scratch, int scans, int points) {
  octomap::ScanGraph graph;
  for (int s = 0; s < scans; ++s) {
    auto* cloud = new octomap::Pointcloud();
    for (int p = 0; p < points; ++p)
      cloud->push_back(1.0f + 0.1f * static_cast<float>(p), 0.5f, 0.2f);
    graph.addNode(cloud, octomath::Pose6D(0.1f * static_cast<float>(s), 0, 0, 0, 0, 0));
  }
  const std::string path = scratch / "scans.graph";
  EXPECT_TRUE(graph.writeBinary(path));
  return path;
}

TEST(cliUser, VersionPrintsTheProjectVersion) {
  Scratch scratch;
  for (const char* spelling : {"--version", "version"}) {
    const RunResult r = runOctovk({spelling}, scratch.dir());
    EXPECT_EQ(r.exit_code, 0) << spelling << ": " << r.err;
    EXPECT_EQ(r.out, std::string("octovk ") + OCTOVK_VERSION + "\n") << spelling;
    EXPECT_EQ(r.err, "") << spelling;
  }
  const RunResult help = runOctovk({"--help"}, scratch.dir());
  EXPECT_NE(help.out.find("--version"), std::string::npos);
}

// Issue 30.6: unset, the mapping commands run lavapipe without worker threads; the user's setting
// wins; `octovk devices` says which holds (on lavapipe only: GPU drivers ignore the variable).
TEST(cliUser, LavapipeThreadsAreChosenUnlessTheUserSetsThem) {
  Scratch scratch;
  const std::string cli = quote(OCTOVK_PATH(OCTOVK_CLI));
  const RunResult unset = runShell("env -u LP_NUM_THREADS " + cli + " devices", scratch.dir());
  const RunResult set = runShell("LP_NUM_THREADS=3 " + cli + " devices", scratch.dir());
  ASSERT_EQ(unset.exit_code, 0) << unset.err;
  ASSERT_EQ(set.exit_code, 0) << set.err;
  const std::size_t selected = unset.out.find("selected: ");
  ASSERT_NE(selected, std::string::npos) << unset.out;
  if (unset.out.find("llvmpipe", selected) != std::string::npos) {
    EXPECT_NE(unset.out.find("lavapipe threads: LP_NUM_THREADS=0, octovk's choice"),
              std::string::npos)
        << unset.out;
    EXPECT_NE(set.out.find("lavapipe threads: LP_NUM_THREADS=3, from the environment"),
              std::string::npos)
        << set.out;
  } else {
    EXPECT_EQ(unset.out.find("lavapipe threads"), std::string::npos) << unset.out;
  }
}

// The environment and exit codes are described once, not in every command's help.
TEST(cliUser, EnvironmentAndExitCodesAreOneHelpTopic) {
  Scratch scratch;
  const RunResult env = runOctovk({"help", "environment"}, scratch.dir());
  EXPECT_EQ(env.exit_code, 0) << env.err;
  for (const char* word :
       {"OCTOVK_DEVICE", "LP_NUM_THREADS", "OCTOVK_CACHE_DIR", "Exit codes", "128+N"})
    EXPECT_NE(env.out.find(word), std::string::npos) << word;
  for (const char* command :
       {"integrate", "convert", "info", "render", "export", "edit", "distance", "devices"}) {
    const RunResult r = runOctovk({command, "--help"}, scratch.dir());
    EXPECT_EQ(r.exit_code, 0) << command;
    EXPECT_EQ(r.out.find("OCTOVK_CACHE_DIR"), std::string::npos) << command;
    EXPECT_NE(r.out.find("octovk help environment"), std::string::npos) << command;
  }
}

// Every command's help ends with examples, and each example's options are ones the command
// takes (run in an empty folder, each stops at its missing input, after parsing every option).
TEST(cliUser, EveryCommandsHelpHasExamplesThatParse) {
  Scratch scratch;
  for (const std::string command :
       {"integrate", "convert", "info", "render", "export", "edit", "distance", "devices"}) {
    const RunResult help = runOctovk({command, "--help"}, scratch.dir());
    const std::size_t at = help.out.find("\nExamples:\n");
    ASSERT_NE(at, std::string::npos) << command;
    std::istringstream lines(help.out.substr(at + 11));
    std::vector<std::string> examples;
    for (std::string line; std::getline(lines, line) && !line.empty();) {
      if (line.rfind("    ", 0) == 0 && !examples.empty())
        examples.back() += line;  // a continuation
      else
        examples.push_back(line);
    }
    EXPECT_GE(examples.size(), 2u) << command;
    for (const std::string& example : examples) {
      std::istringstream words(example);
      std::vector<std::string> args;
      for (std::string word; words >> word;) args.push_back(word);
      if (args.empty() || args.front() != "octovk") continue;  // e.g. VAR=value octovk ...
      args.erase(args.begin());
      EXPECT_EQ(args.front(), command) << example;
      const RunResult r = runOctovk(args, scratch.dir());
      for (const char* parse_error : {"unknown option", "needs", "expects", "takes no"})
        EXPECT_EQ(r.err.find(parse_error), std::string::npos) << example << ": " << r.err;
    }
  }
}

// Each command's help is short (issue 30: integrate's was 101 lines): the long explanations are
// in docs/cli.md, and the help's last line names the section there, which must exist.
TEST(cliUser, EveryCommandsHelpIsShortAndPointsToItsSection) {
  Scratch scratch;
  std::ifstream file(std::string(OCTOVK_SOURCE_DIR) + "/docs/cli.md");
  ASSERT_TRUE(file) << "docs/cli.md";
  const std::string docs((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  for (const std::string command :
       {"integrate", "convert", "info", "render", "export", "edit", "distance", "devices"}) {
    const RunResult help = runOctovk({command, "--help"}, scratch.dir());
    EXPECT_LE(std::count(help.out.begin(), help.out.end(), '\n'), 45) << help.out;
    const std::string pointer = "\nDetails: docs/cli.md, '";
    const std::size_t at = help.out.rfind(pointer);
    ASSERT_NE(at, std::string::npos) << help.out;
    EXPECT_EQ(help.out.find('\n', at + 1), help.out.size() - 1) << "not the last line: " << command;
    // "'integrate', 'Depth images (TUM RGB-D)'.": each quoted name heads a section or paragraph.
    std::istringstream sections(help.out.substr(at + pointer.size() - 1));
    for (std::string quoted; std::getline(sections, quoted, '\'');) {
      if (!std::getline(sections, quoted, '\'')) break;
      EXPECT_TRUE(docs.find("\n## " + quoted + "\n") != std::string::npos ||
                  docs.find("\n**" + quoted + ".**") != std::string::npos)
          << command << ": docs/cli.md has no section '" << quoted << "'";
    }
  }
}

TEST(cliUser, Graph2treeSpellingsGetTheOptionToUse) {
  Scratch scratch;
  const std::string graph = writeGraph(scratch, 1, 3);
  const std::string out = scratch / "out.bt";
  struct Case {
    std::vector<std::string> args;
    std::string mention;
  };
  const std::vector<Case> cases = {
      {{"integrate", graph, "-o", out, "-res", "0.1"}, "did you mean --resolution?"},
      {{"integrate", graph, "-o", out, "--resoluton", "0.1"}, "did you mean --resolution?"},
      {{"integrate", graph, "-o", out, "-discretize"}, "did you mean --discretize?"},
      {{"integrate", graph, "-o", out, "--max_range", "5"}, "did you mean --max-range?"},
      {{"integrate", graph, "-o", out, "-clamping", "0.1", "0.9"},
       "did you mean --clamping-min A and --clamping-max B?"},
      {{"integrate", "-i", graph, "-o", out}, "needs no option"},
      {{"distance", "map.bt", "--max-dist", "2"}, "did you mean --max-distance?"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.args[c.args.size() > 4 ? 4 : 1]);
    expectOneError(runOctovk(c.args, scratch.dir()), 2, {c.mention}, scratch);
  }
  // Nothing close: no guess.
  const RunResult bogus = runOctovk({"integrate", graph, "-o", out, "--bogus"}, scratch.dir());
  expectOneError(bogus, 2, {"'--bogus'"}, scratch);
  EXPECT_EQ(bogus.err.find("did you mean"), std::string::npos) << bogus.err;
}

TEST(cliUser, AMapGivenToIntegrateIsNamedAsAMap) {
  Scratch scratch;
  octomap::OcTree tree(0.1);
  tree.updateNode(octomap::point3d(0.05f, 0.05f, 0.05f), true);
  // Named as graphs, too: the header decides, not the extension.
  const std::string bt = scratch / "map_bt.graph";
  const std::string ot = scratch / "map_ot.graph";
  ASSERT_TRUE(tree.writeBinary(bt));
  ASSERT_TRUE(tree.write(ot));
  expectOneError(runOctovk({"integrate", bt, "-o", scratch / "out.bt"}, scratch.dir()), 2,
                 {"'" + bt + "' is an OctoMap map (.bt), not a scan graph", "octovk info"},
                 scratch);
  expectOneError(runOctovk({"integrate", ot, "-o", scratch / "out.bt"}, scratch.dir()), 2,
                 {"'" + ot + "' is an OctoMap map (.ot), not a scan graph"}, scratch);
}

TEST(cliUser, AnEmptyScanGraphIsAnError) {
  Scratch scratch;
  {
    const std::string graph = writeGraph(scratch, 0, 0);
    expectOneError(runOctovk({"integrate", graph, "-o", scratch / "out.bt"}, scratch.dir()), 1,
                   {"'" + graph + "' holds no scans"}, scratch);
  }
  {
    const std::string graph = writeGraph(scratch, 2, 0);
    expectOneError(runOctovk({"integrate", graph, "-o", scratch / "out.bt"}, scratch.dir()), 1,
                   {"'" + graph + "' holds 2 scan(s) but no points"}, scratch);
  }
}

TEST(cliUser, IntegratePrintsTheDeviceOnce) {
  Scratch scratch;
  const std::string graph = writeGraph(scratch, 2, 5);
  const RunResult r =
      runOctovk({"integrate", graph, "-o", scratch / "map.bt", "--quiet"}, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::size_t count = 0;
  for (std::size_t at = r.out.find("device:"); at != std::string::npos;
       at = r.out.find("device:", at + 1))
    ++count;
  EXPECT_EQ(count, 1u) << r.out;
  EXPECT_EQ(r.out.rfind("device: ", 0), 0u) << r.out;
  EXPECT_NE(r.out.find("scans:         2\n"), std::string::npos) << r.out;
}

TEST(cliUser, EditSaysWhatItClearedAndWhichNodesItCounts) {
  Scratch scratch;
  // A 16 x 16 floor of occupied cells: writeBinary prunes its uniform blocks, so the .bt holds
  // fewer nodes than the map in memory.
  octomap::OcTree tree(0.1);
  for (int x = 0; x < 16; ++x)
    for (int y = 0; y < 16; ++y)
      tree.updateNode(octomap::point3d(0.05f + 0.1f * static_cast<float>(x),
                                       0.05f + 0.1f * static_cast<float>(y), 0.05f),
                      true);
  const std::string map = scratch / "in.bt";
  ASSERT_TRUE(tree.writeBinary(map));
  const std::string out = scratch / "edited.bt";
  const RunResult r = runOctovk(
      {"edit", map, "--clear-box", "0", "0", "-1", "0.4", "0.4", "1", "-o", out}, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The leaves OctoMap's leaf_bbx_iterator visits for the box: the 5 x 5 occupied cells.
  std::size_t in_box = 0;
  for (auto it = tree.begin_leafs_bbx(octomap::point3d(0, 0, -1), octomap::point3d(0.4f, 0.4f, 1));
       it != tree.end_leafs_bbx(); ++it)
    ++in_box;
  EXPECT_EQ(in_box, 25u);
  EXPECT_NE(r.out.find(": " + std::to_string(in_box) + " leaves set free (" +
                       std::to_string(in_box) + " of them were occupied)"),
            std::string::npos)
      << r.out;
  octomap::OcTree written(0.1);
  ASSERT_TRUE(written.readBinary(out));
  const std::string counted = std::to_string(written.size()) + " in " + out;
  EXPECT_NE(r.out.find("after, in memory; " + counted), std::string::npos) << r.out;
  const RunResult info = runOctovk({"info", out}, scratch.dir());
  ASSERT_EQ(info.exit_code, 0) << info.err;
  const std::string info_nodes = "nodes:           " + std::to_string(written.size());
  EXPECT_NE(info.out.find(info_nodes), std::string::npos) << info.out;
}

// integrate's counts say what they count: the nodes in memory (graph2tree's "Tree size") and
// those in each file as 'octovk info' counts them; a .bt is max-likelihood and pruned, so it can
// hold fewer. Two scans hit the 8 cells of a block, the second only half of them: in memory
// they differ and stay apart; in the .bt all are occupied and merge.
TEST(cliUser, IntegrateCountsTheNodesOfEachFile) {
  Scratch scratch;
  octomap::ScanGraph graph;
  for (int s = 0; s < 2; ++s) {
    auto* cloud = new octomap::Pointcloud();
    for (int i = 0; i < 8; ++i)
      if (s == 0 || i % 2 == 0)
        cloud->push_back(2.05f + 0.1f * float(i & 1), 0.05f + 0.1f * float((i >> 1) & 1),
                         0.05f + 0.1f * float(i >> 2));
    graph.addNode(cloud, octomath::Pose6D(0, 0, 0, 0, 0, 0));
  }
  const std::string path = scratch / "block.graph";
  ASSERT_TRUE(graph.writeBinary(path));
  const std::string bt = scratch / "m.bt", ot = scratch / "m.ot";
  const RunResult r =
      runOctovk({"integrate", path, "-r", "0.1", "-o", bt, "-o", ot, "-q"}, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  octomap::OcTree from_bt(0.1);
  ASSERT_TRUE(from_bt.readBinary(bt));
  std::unique_ptr<octomap::AbstractOcTree> from_ot(octomap::AbstractOcTree::read(ot));
  ASSERT_TRUE(from_ot);
  EXPECT_LT(from_bt.size(), from_ot->size()) << "the test needs a .bt that prunes further";
  EXPECT_NE(r.out.find("nodes:         " + std::to_string(from_ot->size()) + " in memory"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find(bt + " " + std::to_string(from_bt.size()) + " (max-likelihood, pruned), " +
                       ot + " " + std::to_string(from_ot->size()) + ": as 'octovk info' counts"),
            std::string::npos)
      << r.out;
  for (const auto& [file, size] : {std::pair{bt, from_bt.size()}, {ot, from_ot->size()}}) {
    const RunResult info = runOctovk({"info", file}, scratch.dir());
    EXPECT_NE(info.out.find("nodes:           " + std::to_string(size) + "\n"), std::string::npos)
        << info.out;
  }
}

}  // namespace

namespace {

// A second -o for a command that writes one file names the command, what it writes and both
// paths, for every such command, in one line (exit 2), before any work.
TEST(cliUser, ASecondOutputIsNamedForEveryOneOutputCommand) {
  Scratch scratch;
  const std::vector<std::vector<std::string>> runs = {
      {"render", "m.bt", "-o", "a.png", "-o", "b.png"},
      {"distance", "m.bt", "--box", "0", "0", "0", "1", "1", "1", "-o", "a.png", "-o", "b.png"},
      {"export", "m.bt", "-o", "a.ply", "-o", "b.ply"},
      {"edit", "m.bt", "--clear-box", "0", "0", "0", "1", "1", "1", "-o", "a.bt", "-o", "b.bt"},
      {"convert", "folder", "-o", "a.graph", "-o", "b.graph"}};
  for (const auto& args : runs) {
    const RunResult r = runOctovk(args, scratch.dir());
    expectOneError(r, 2, {args[0] + " writes one", "give -o once", "'a.", "'b."}, scratch);
  }
}

}  // namespace
}  // namespace octovk::test
