// The map store (issue 31): tiles and the tree rebuilt from them against OctoMap's own trees
// (graph2tree's files, trees built with OctoMap), and the SQLite store through the program against
// graph2tree: export after integrate --store, a second run continuing the map, a killed writer.
#include "store/store.hpp"

#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <regex>
#include <sstream>
#include <thread>

#include "cli_support.hpp"
#include "map/store_access.hpp"
#include "octovk/octomap_io.hpp"
#include "octovk/store.hpp"
#include "payload_oracle.hpp"
#include "store/tiles.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

using test::quote;
using test::readFile;
using test::runOctovk;
using test::RunResult;
using test::runShell;
using test::Scratch;
namespace fs = std::filesystem;

// OctoMap's tree as a host tree (breadth first, as fromOcTree lays it out), on the host.
HostTree hostTreeOf(const octomap::OcTree& tree) {
  HostTree host;
  const octomap::OcTreeNode* root = tree.getRoot();
  host.root_exists = root != nullptr;
  if (!root) return host;
  const HostTree::Node leaf{0.0f, 0xFFFFFFFFu, 0, 0};
  host.nodes.assign(8, leaf);
  host.nodes[0].log_odds = root->getLogOdds();
  std::vector<std::pair<const octomap::OcTreeNode*, std::size_t>> queue{{root, 0}};
  for (std::size_t head = 0; head < queue.size(); ++head) {
    const auto [node, index] = queue[head];
    if (!tree.nodeHasChildren(node)) continue;
    const auto block = static_cast<std::uint32_t>(host.nodes.size() / 8);
    host.nodes.resize(host.nodes.size() + 8, leaf);
    std::uint32_t mask = 0;
    for (unsigned i = 0; i < 8; ++i) {
      if (!tree.nodeChildExists(node, i)) continue;
      const octomap::OcTreeNode* child = tree.getNodeChild(node, i);
      host.nodes[block * 8 + i].log_odds = child->getLogOdds();
      queue.emplace_back(child, block * 8 + i);
      mask |= 1u << i;
    }
    host.nodes[index].children = block;
    host.nodes[index].mask = mask;
  }
  return host;
}

// OctoMap's .ot bytes of a tree (OcTree::write, as graph2tree writes X.bt.ot).
std::string otBytes(const octomap::OcTree& tree) {
  std::ostringstream out;
  tree.write(out);
  return out.str();
}

// The .ot bytes of `tree` after tiles at `depth` -> tree -> OctoMap's writer.
std::string roundTrip(const octomap::OcTree& tree, unsigned depth, std::size_t* tile_count) {
  const std::vector<store::Tile> tiles = store::tilesOf(hostTreeOf(tree), depth);
  if (tile_count) *tile_count = tiles.size();
  MapParams params;
  params.resolution = tree.getResolution();
  return otBytes(*store::ocTreeOf(store::treeFromTiles(tiles, depth), params));
}

octomap::OcTreeKey keyOf(int x, int y, int z) {
  return octomap::OcTreeKey(static_cast<octomap::key_type>(x), static_cast<octomap::key_type>(y),
                            static_cast<octomap::key_type>(z));
}

// graph2tree's .ot of OctoMap's sample scan, cut at every depth and rebuilt: byte-identical.
TEST(StoreTiles, RoundTripOfGraph2treeMapIsByteIdentical) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  Scratch scratch("store");
  const std::string graph =
      std::string(OCTOVK_PATH(OCTOVK_OCTOMAP_DATA_DIR)) + "/spherical_scan.graph";
  const std::string ref = scratch / "ref.bt";
  const RunResult g2t = runShell(quote(OCTOVK_PATH(OCTOVK_GRAPH2TREE)) + " -i " + quote(graph) +
                                     " -o " + quote(ref) + " -res 0.05",
                                 scratch.dir());
  ASSERT_EQ(g2t.exit_code, 0) << g2t.out << g2t.err;
  const std::string expected = readFile(ref + ".ot");
  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(ref + ".ot"));
  auto* tree = dynamic_cast<octomap::OcTree*>(read.get());
  ASSERT_NE(tree, nullptr);
  ASSERT_EQ(otBytes(*tree), expected);
  for (unsigned depth : {1u, 4u, 6u, 8u, store::kTileDepth, 13u, 16u}) {
    std::size_t tiles = 0;
    EXPECT_EQ(roundTrip(*tree, depth, &tiles), expected) << "tile depth " << depth;
    EXPECT_GT(tiles, 0u);
  }
}

// Pruning across tiles: uniform regions larger than a tile are single leaves above the tile
// depth in OctoMap's tree (tiles of their own), and 8 equal tile roots merge into their parent.
TEST(StoreTiles, PruningAcrossTilesAsOctoMap) {
  octomap::OcTree tree(0.1);
  // A 16^3 cube of free cells (pruned to one leaf at depth 12), a 4^3 cube of occupied cells
  // beside it (one leaf at depth 14), and scattered cells of both kinds.
  for (int x = 0; x < 16; ++x)
    for (int y = 0; y < 16; ++y)
      for (int z = 0; z < 16; ++z) tree.updateNode(keyOf(32768 + x, 32768 + y, 32768 + z), false);
  for (int x = 16; x < 20; ++x)
    for (int y = 0; y < 4; ++y)
      for (int z = 0; z < 4; ++z) tree.updateNode(keyOf(32768 + x, 32768 + y, 32768 + z), true);
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> cell(32700, 32840);
  for (int i = 0; i < 3000; ++i)
    tree.updateNode(keyOf(cell(rng), cell(rng), cell(rng)), i % 3 == 0);
  // A cell flipped back: its cube is uniform again and OctoMap prunes it again.
  tree.updateNode(keyOf(32770, 32770, 32770), true);
  tree.updateNode(keyOf(32770, 32770, 32770), false);
  const std::string expected = otBytes(tree);
  for (unsigned depth = 1; depth <= 16; ++depth)
    EXPECT_EQ(roundTrip(tree, depth, nullptr), expected) << "tile depth " << depth;
  // A uniform 16^3 cube alone: one leaf at depth 12, a tile of its own above tile depth 14.
  octomap::OcTree uniform(0.1);
  for (int x = 0; x < 16; ++x)
    for (int y = 0; y < 16; ++y)
      for (int z = 0; z < 16; ++z) uniform.updateNode(keyOf(x, y, z), true);
  const std::vector<store::Tile> tiles = store::tilesOf(hostTreeOf(uniform), 14);
  ASSERT_EQ(tiles.size(), 1u);
  EXPECT_EQ(store::tileKeyDepth(tiles[0].key), 12u);
  EXPECT_EQ(tiles[0].body.size(), 5u);
  EXPECT_EQ(roundTrip(uniform, 14, nullptr), otBytes(uniform));
  EXPECT_EQ(roundTrip(octomap::OcTree(0.1), 8, nullptr), otBytes(octomap::OcTree(0.1)));
}

// Tiles of a tree OctoMap left unpruned (lazy updates): the rebuilt tree is OctoMap's after
// updateInnerOccupancy() and prune(): 8 equal tile roots become one leaf above them.
TEST(StoreTiles, EqualSiblingTilesArePrunedAsOctoMapPrunes) {
  octomap::OcTree lazy(0.1);
  for (int i = 0; i < 8; ++i)  // 8 siblings at depth 16, then 8 at depth 16 under another parent
    for (int base : {0, 64})
      lazy.updateNode(keyOf(base + (i & 1), (i >> 1) & 1, i >> 2), true, true);
  lazy.updateNode(keyOf(200, 0, 0), false, true);
  const std::vector<store::Tile> tiles = store::tilesOf(hostTreeOf(lazy), 16);
  EXPECT_EQ(tiles.size(), 17u);
  MapParams params;
  params.resolution = 0.1;
  const std::string rebuilt = otBytes(*store::ocTreeOf(store::treeFromTiles(tiles, 16), params));
  lazy.updateInnerOccupancy();
  lazy.prune();
  EXPECT_EQ(rebuilt, otBytes(lazy));
  EXPECT_EQ(store::tilesOf(hostTreeOf(lazy), 16).size(), 3u);  // two leaves at depth 15, one at 16
}

TEST(StoreTiles, KeysSortInNodeStreamOrderAndNameTheirCorner) {
  const std::uint64_t a = store::tileKey(2, 0b000111);  // child 0, then 7
  const std::uint64_t b = store::tileKey(1, 0b001);     // child 1
  const std::uint64_t c = store::tileKey(2, 0b001000);  // child 1, then 0: after its parent
  EXPECT_LT(a, b);
  EXPECT_LT(b, c);
  EXPECT_EQ(store::tileKeyDepth(c), 2u);
  const Key corner = store::tileKeyCorner(store::tileKey(2, 0b111001));  // x y z, then x
  EXPECT_EQ(corner, (Key{0x8000 | 0x4000, 0x8000, 0x8000}));
  // A cell's path is the corner's inverse: the tile holding it at depth 2 is the one above.
  EXPECT_EQ(store::cellPath(corner) >> (3 * 14), 0b111001u);
  const Key cell{0x1234, 0xFEDC, 0x0F0F};
  EXPECT_EQ(store::tileKeyCorner(store::tileKey(16, store::cellPath(cell))), cell);
}

// A damaged body or key is an error naming the tile, never a wrong tree.
TEST(StoreTiles, DamagedTilesAreRefusedWithTheirName) {
  octomap::OcTree tree(0.1);
  for (int i = 0; i < 50; ++i) tree.updateNode(keyOf(32768 + i, 32768, 32768), true);
  std::vector<store::Tile> tiles = store::tilesOf(hostTreeOf(tree), 12);
  ASSERT_GT(tiles.size(), 2u);
  const auto refused = [&](std::vector<store::Tile> damaged, const std::string& why) {
    try {
      store::treeFromTiles(damaged, 12);
      ADD_FAILURE() << "accepted: " << why;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kFormat);
      EXPECT_NE(std::string(e.what()).find("tile "), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  auto cut = tiles;
  cut[1].body.pop_back();
  refused(cut, "runs past its end");
  auto longer = tiles;
  longer[1].body += "x";
  refused(longer, "follow its last node record");
  auto twice = tiles;
  twice.push_back(tiles[0]);
  refused(twice, "already covers");
  auto nan = tiles;
  const float bad = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan[0].body.data(), &bad, sizeof(float));
  refused(nan, "not a finite number");
  auto deep = tiles;
  deep[0].key = store::tileKey(13, 0);
  refused(deep, "no tile key");
}

}  // namespace
}  // namespace octovk

namespace octovk {
namespace {

using test::OctovkProcess;
using test::pollUntil;

// A small scan graph: `count` scans of a 4 x 3 x 2.5 m room's walls and floor (about 300 points
// each) seen from poses along a line, `shift` moving the whole room.
std::vector<GraphScan> roomScans(std::size_t count, float shift) {
  std::vector<GraphScan> scans(count);
  for (std::size_t s = 0; s < count; ++s) {
    GraphScan& scan = scans[s];
    const float t = 0.15f * static_cast<float>(s);
    scan.T_world_sensor.translation = Eigen::Vector3f(t + shift, 0.2f * std::sin(t), 1.0f);
    for (int i = 0; i < 300; ++i) {
      const float u = static_cast<float>(i % 20) / 20.0f, v = static_cast<float>(i / 20) / 15.0f;
      Eigen::Vector3f world;
      switch (i % 3) {
        case 0:
          world = {4.0f + shift, -1.5f + 3.0f * u, 2.5f * v};
          break;
        case 1:
          world = {4.0f * u + shift, 1.5f, 2.5f * v};
          break;
        default:
          world = {4.0f * u + shift, -1.5f + 3.0f * v, 0.0f};
          break;
      }
      scan.points_sensor.push_back(world - scan.T_world_sensor.translation);
    }
  }
  return scans;
}

void writeGraph(const std::string& path, const std::vector<GraphScan>& scans) {
  writeScanGraph(path, scans.size(), [&](std::size_t i) { return scans[i]; });
}

// graph2tree's .ot of `graph` at 0.1 m (its X.bt.ot).
std::string graph2treeOt(const std::string& graph, const Scratch& scratch) {
  const std::string out = scratch / "graph2tree.bt";
  const RunResult r = runShell(quote(OCTOVK_PATH(OCTOVK_GRAPH2TREE)) + " -i " + quote(graph) +
                                   " -o " + quote(out) + " -res 0.1",
                               scratch.dir());
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  return readFile(out + ".ot");
}

std::string exportOt(const std::string& store, const Scratch& scratch) {
  const std::string out = scratch / "export.ot";
  const RunResult r = runOctovk({"store", "export", store, "-o", out}, scratch.dir());
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  return readFile(out);
}

// The summary's "store writes:" line: the bytes written per scan.
void printStoreWrites(const std::string& summary) {
  const std::size_t at = summary.find("store writes:");
  ASSERT_NE(at, std::string::npos) << summary;
  std::cout << "[ bytes    ] " << summary.substr(at, summary.find('\n', at) - at) << "\n";
}

TEST(StoreCli, ExportAfterIntegrateIsGraph2treesMap) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  Scratch scratch("store");
  const std::string graph = scratch / "room.graph";
  writeGraph(graph, roomScans(6, 0.0f));
  const std::string store = scratch / "map.sqlite";
  const RunResult r =
      runOctovk({"integrate", graph, "--store", store, "-r", "0.1", "-q"}, scratch.dir());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  printStoreWrites(r.out);
  const std::string expected = graph2treeOt(graph, scratch);
  EXPECT_EQ(exportOt(store, scratch), expected);
  // .bt too: OctoMap's writer, with the stored sensor model.
  const RunResult bt = runOctovk({"store", "export", store, "-o", scratch / "e.bt"}, scratch.dir());
  ASSERT_EQ(bt.exit_code, 0) << bt.err;
  EXPECT_EQ(readFile(scratch / "e.bt"), readFile(scratch / "graph2tree.bt"));
  const RunResult log = runOctovk({"store", "log", store}, scratch.dir());
  ASSERT_EQ(log.exit_code, 0) << log.err;
  std::string lines;
  for (int i = 0; i < 6; ++i)
    lines += std::to_string(i + 1) + " " + graph + " " + std::to_string(i) + "\n";
  EXPECT_EQ(log.out, lines);
}

TEST(StoreCli, SecondRunContinuesTheMapAndKeepsItsResolution) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  Scratch scratch("store");
  const std::vector<GraphScan> a = roomScans(4, 0.0f), b = roomScans(3, 0.7f);
  const std::string graph_a = scratch / "a.graph", graph_b = scratch / "b.graph";
  writeGraph(graph_a, a);
  writeGraph(graph_b, b);
  const std::string store = scratch / "map.sqlite";
  ASSERT_EQ(runOctovk({"integrate", graph_a, "--store", store, "-r", "0.1", "-q"}, scratch.dir())
                .exit_code,
            0);
  // Another resolution is refused, and the store is left as it was.
  const RunResult refused =
      runOctovk({"integrate", graph_b, "--store", store, "-r", "0.05", "-q"}, scratch.dir());
  test::expectOneErrorLine(refused, 2, {"--resolution 0.05", "resolution 0.1", store});
  // No --resolution: the map's own; the run starts from the committed map.
  const RunResult second = runOctovk(
      {"integrate", graph_b, "--store", store, "-q", "-o", scratch / "direct.ot"}, scratch.dir());
  ASSERT_EQ(second.exit_code, 0) << second.out << second.err;
  EXPECT_NE(second.out.find("(continued): 3 scans committed"), std::string::npos) << second.out;
  printStoreWrites(second.out);
  std::vector<GraphScan> both = a;
  both.insert(both.end(), b.begin(), b.end());
  const std::string graph_both = scratch / "both.graph";
  writeGraph(graph_both, both);
  const std::string expected = graph2treeOt(graph_both, scratch);
  EXPECT_EQ(exportOt(store, scratch), expected);
  EXPECT_EQ(readFile(scratch / "direct.ot"), expected);  // the run's own map, loaded from the store
  const RunResult log = runOctovk({"store", "log", store}, scratch.dir());
  std::string lines;
  for (int i = 0; i < 7; ++i)
    lines += std::to_string(i + 1) + " " + (i < 4 ? graph_a : graph_b) + " " +
             std::to_string(i < 4 ? i : i - 4) + "\n";
  EXPECT_EQ(log.out, lines);
}

// Two writers integrate into one map at once, their scans overlapping: the store takes their
// scans one at a time (each writer reloads the map when the other committed meanwhile), and the
// map is OctoMap's (graph2tree's) on every committed scan in the log's order.
void expectTwoWritersGiveTheLogsMap(const std::string& store_location, const Scratch& scratch) {
  const std::vector<GraphScan> a = roomScans(25, 0.0f), b = roomScans(25, 0.35f);
  const std::string graph_a = scratch / "a.graph", graph_b = scratch / "b.graph";
  writeGraph(graph_a, a);
  writeGraph(graph_b, b);
  const fs::path dir_a = scratch.dir() / "wa", dir_b = scratch.dir() / "wb";
  fs::create_directories(dir_a);
  fs::create_directories(dir_b);
  RunResult ra, rb;
  {
    OctovkProcess wa(
        {"integrate", graph_a, "--store", store_location, "--map", "shared", "-r", "0.1", "-q"},
        dir_a);
    OctovkProcess wb(
        {"integrate", graph_b, "--store", store_location, "--map", "shared", "-r", "0.1", "-q"},
        dir_b);
    ASSERT_TRUE(wa.started() && wb.started());
    ra = wa.wait();
    rb = wb.wait();
  }
  ASSERT_EQ(ra.exit_code, 0) << ra.out << ra.err;
  ASSERT_EQ(rb.exit_code, 0) << rb.out << rb.err;
  auto store = store::Store::open(store_location, false);
  const std::vector<store::LogEntry> log = store->log("shared");
  ASSERT_EQ(log.size(), a.size() + b.size());
  std::vector<GraphScan> in_order;
  std::size_t switches = 0;
  for (std::size_t i = 0; i < log.size(); ++i) {
    ASSERT_TRUE(log[i].source == graph_a || log[i].source == graph_b) << log[i].source;
    const std::vector<GraphScan>& from = log[i].source == graph_a ? a : b;
    ASSERT_LT(log[i].scan, from.size());
    in_order.push_back(from[log[i].scan]);
    if (i > 0 && log[i].source != log[i - 1].source) ++switches;
  }
  std::cout << "[ writers  ] the log switches writer " << switches << " times\n";
  const std::string graph_log = scratch / "log.graph";
  writeGraph(graph_log, in_order);
  const std::string out = scratch / "shared.ot";
  const RunResult e =
      runOctovk({"store", "export", store_location, "--map", "shared", "-o", out}, scratch.dir());
  ASSERT_EQ(e.exit_code, 0) << e.err;
  EXPECT_EQ(readFile(out), graph2treeOt(graph_log, scratch));
}

TEST(StoreCli, TwoWritersAtOnceGiveTheMapOfTheLog) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  Scratch scratch("store");
  expectTwoWritersGiveTheLogsMap(scratch / "shared.sqlite", scratch);
}

// A writer killed mid-run: the store holds exactly the scans its log lists, as OctoMap builds
// them (graph2tree on a graph of those scans), and a later run goes on from there.
void expectKilledWriterLeavesItsLog(const std::string& location, const Scratch& scratch) {
  const std::vector<GraphScan> scans = roomScans(120, 0.0f);
  const std::string graph = scratch / "long.graph";
  writeGraph(graph, scans);
  const std::string map = "killed";
  std::size_t committed = 0;
  {
    OctovkProcess writer({"integrate", graph, "--store", location, "--map", map, "-r", "0.1", "-q"},
                         scratch.dir());
    ASSERT_TRUE(writer.started());
    const bool some = pollUntil(
        [&] {
          try {
            auto store = store::Store::open(location, false);
            committed = store->map(map) ? store->log(map).size() : 0;
          } catch (const Error&) {
            committed = 0;  // not created yet
          }
          return committed >= 3;
        },
        std::chrono::seconds(120));
    writer.signal(SIGKILL);
    const RunResult r = writer.wait();
    ASSERT_TRUE(some) << r.out << r.err;
    EXPECT_EQ(r.exit_code, 128 + SIGKILL) << "the writer ended before it was killed: " << r.out;
  }
  auto store = store::Store::open(location, false);
  const std::vector<store::LogEntry> log = store->log(map);
  ASSERT_GE(log.size(), committed);
  ASSERT_LT(log.size(), scans.size());
  std::cout << "[ killed   ] after " << log.size() << " of " << scans.size()
            << " scans committed\n";
  for (std::size_t i = 0; i < log.size(); ++i) {
    EXPECT_EQ(log[i].seq, i + 1);
    EXPECT_EQ(log[i].source, graph);
    EXPECT_EQ(log[i].scan, i);
  }
  const std::vector<GraphScan> kept(scans.begin(), scans.begin() + static_cast<long>(log.size()));
  const std::string graph_kept = scratch / "kept.graph";
  writeGraph(graph_kept, kept);
  const std::string out = scratch / "kept.ot";
  const RunResult e =
      runOctovk({"store", "export", location, "--map", map, "-o", out}, scratch.dir());
  ASSERT_EQ(e.exit_code, 0) << e.err;
  EXPECT_EQ(readFile(out), graph2treeOt(graph_kept, scratch));
}

// `store follow` while a writer commits: after its first look the local file is the map of the
// scans committed then, at the end that of all of them (graph2tree's on the same scans), and its
// later looks read only tiles written since the one before: together no more than the writer
// wrote.
void expectFollowerKeepsTheMap(const std::string& location, const std::string& map,
                               const Scratch& scratch, const std::string& interval = "0.02") {
  const std::vector<GraphScan> a = roomScans(4, 0.0f), b = roomScans(3, 0.7f);
  std::vector<GraphScan> both = a;
  both.insert(both.end(), b.begin(), b.end());
  const std::string graph_a = scratch / "a.graph", graph_b = scratch / "b.graph",
                    graph_both = scratch / "both.graph";
  writeGraph(graph_a, a);
  writeGraph(graph_b, b);
  writeGraph(graph_both, both);
  const RunResult first = runOctovk(
      {"integrate", graph_a, "--store", location, "--map", map, "-r", "0.1", "-q"}, scratch.dir());
  ASSERT_EQ(first.exit_code, 0) << first.out << first.err;
  const std::string live = scratch / "live.ot";
  const fs::path dir = scratch.dir() / "follower";
  fs::create_directories(dir);
  OctovkProcess follower({"store", "follow", location, "--map", map, "-o", live, "--until-seq", "7",
                          "--interval", interval},
                         dir);
  ASSERT_TRUE(follower.started());
  ASSERT_TRUE(pollUntil([&] { return fs::exists(live); }, std::chrono::seconds(60)));
  EXPECT_EQ(readFile(live), graph2treeOt(graph_a, scratch));
  const RunResult second =
      runOctovk({"integrate", graph_b, "--store", location, "--map", map, "-q"}, scratch.dir());
  ASSERT_EQ(second.exit_code, 0) << second.out << second.err;
  const RunResult r = follower.wait();
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_EQ(readFile(live), graph2treeOt(graph_both, scratch));
  EXPECT_TRUE(test::temporariesIn(scratch.dir()).empty());
  // One line per look that found a commit: the first at seq 4, the last at seq 7.
  const std::regex line(
      R"(seq (\d+): (\d+) tiles read \((\d+) bytes\), (\d+) dropped; (\d+) nodes in )");
  std::vector<std::pair<unsigned long, unsigned long>> looks;  // seq, tiles read
  for (auto it = std::sregex_iterator(r.out.begin(), r.out.end(), line);
       it != std::sregex_iterator(); ++it)
    looks.emplace_back(std::stoul((*it)[1]), std::stoul((*it)[2]));
  ASSERT_GE(looks.size(), 2u) << r.out;
  EXPECT_EQ(looks.front().first, 4u) << r.out;
  EXPECT_EQ(looks.back().first, 7u) << r.out;
  std::smatch wrote;
  ASSERT_TRUE(std::regex_search(second.out, wrote, std::regex(R"(store writes:\s+(\d+) tiles)")))
      << second.out;
  unsigned long later = 0;
  for (std::size_t i = 1; i < looks.size(); ++i) later += looks[i].second;
  EXPECT_LE(later, std::stoul(wrote[1])) << r.out << second.out;
  EXPECT_GT(later, 0u) << r.out;
  std::cout << "[ follow   ] " << looks.size() << " looks; the first read " << looks.front().second
            << " tiles, the later ones " << later << " (the writer wrote " << wrote[1] << ")\n";
}

TEST(StoreCli, FollowerKeepsALocalCopyCurrent) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  Scratch scratch("store");
  expectFollowerKeepsTheMap(scratch / "map.sqlite", "default", scratch);
}

TEST(StoreCli, FollowRefusesAMissingMapAndABadSeq) {
  Scratch scratch("store");
  const std::string graph = scratch / "room.graph";
  writeGraph(graph, roomScans(2, 0.0f));
  const std::string store = scratch / "map.sqlite";
  ASSERT_EQ(
      runOctovk({"integrate", graph, "--store", store, "-r", "0.1", "-q"}, scratch.dir()).exit_code,
      0);
  test::expectOneErrorLine(
      runOctovk({"store", "follow", store, "--map", "lab", "-o", scratch / "x.ot"}, scratch.dir()),
      1, {"holds no map 'lab'", "octovk store info"});
  test::expectOneErrorLine(
      runOctovk({"store", "follow", store, "-o", scratch / "x.ot", "--until-seq", "0"},
                scratch.dir()),
      2, {"--until-seq 0", "whole number"});
  test::expectOneErrorLine(
      runOctovk({"store", "follow", store, "-o", scratch / "x.ot", "--interval", "-1"},
                scratch.dir()),
      2, {"--interval -1", "seconds"});
  EXPECT_FALSE(fs::exists(scratch / "x.ot"));
}

// The C++ API: StoredMap commits each scan as integrate --store does, two of them on one map
// take turns (each loads the other's scans first), and readStoredMap reads the committed map.
TEST(StoredMapApi, ScansCommitAsOctoMapReplaysTheLog) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch("store");
  const std::string location = scratch / "api.sqlite";
  const std::vector<GraphScan> a = roomScans(4, 0.0f), b = roomScans(4, 0.35f);
  MapParams params;
  params.resolution = 0.1;
  StoredMap one = StoredMap::open(ctx, location, "api", params);
  StoredMap two = StoredMap::open(ctx, location, "api", params);  // exists now: its own params
  const auto insert = [](StoredMap& into, const GraphScan& scan, const std::string& source,
                         std::uint64_t index) {
    std::vector<Eigen::Vector3f> world;
    for (const Eigen::Vector3f& p : scan.points_sensor)
      world.push_back(scan.T_world_sensor.transform(p));
    into.insertPointCloud(world, scan.T_world_sensor.translation, source, index);
  };
  std::vector<GraphScan> in_order;
  for (std::size_t i = 0; i < a.size(); ++i) {
    insert(one, a[i], "a", i);
    in_order.push_back(a[i]);
    insert(two, b[i], "b", i);
    in_order.push_back(b[i]);
  }
  EXPECT_EQ(one.lastSeq(), 7u);
  EXPECT_EQ(two.lastSeq(), 8u);
  const std::string graph = scratch / "log.graph";
  writeGraph(graph, in_order);
  const std::string expected = graph2treeOt(graph, scratch);
  const RunResult exported = runOctovk(
      {"store", "export", location, "--map", "api", "-o", scratch / "export.ot"}, scratch.dir());
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  EXPECT_TRUE(readFile(scratch / "export.ot") == expected) << "export differs from graph2tree's";
  // The writer's own device map is the committed one; readStoredMap reads the same.
  writeMapFile(two.map(), scratch / "two.ot");
  EXPECT_TRUE(readFile(scratch / "two.ot") == expected) << "the writer's map differs";
  OccupancyMap read = readStoredMap(ctx, location, "api");
  EXPECT_EQ(read.params().resolution, 0.1);
  writeMapFile(read, scratch / "read.ot");
  EXPECT_TRUE(readFile(scratch / "read.ot") == expected) << "readStoredMap's map differs";
  const RunResult log = runOctovk({"store", "log", location, "--map", "api"}, scratch.dir());
  EXPECT_EQ(log.out.rfind("1 a 0\n2 b 0\n3 a 1\n", 0), 0u) << log.out;
  // What is refused: a map the store lacks (without parameters to create it), another payload.
  try {
    (void)StoredMap::open(ctx, location, "lab");
    ADD_FAILURE() << "a missing map was opened";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("holds no map 'lab'"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)readStoredMap(ctx, location, "lab"), Error);
  EXPECT_FALSE(store::Store::open(location, false)->map("lab").has_value());
  MapParams color = params;
  color.payload = Payload::kColor;  // a map that exists keeps its own parameters and tree type
  EXPECT_EQ(StoredMap::open(ctx, location, "api", color).map().params().payload, Payload::kNone);
}

// A commit serialises only the tiles on the scan's updated paths (and new ones) when the device
// map is the last commit's plus one scan; the store must still hold exactly the whole map's cut
// after every scan: through free space merging into tiles above the tile depth, a merged region
// expanded again by an obstacle, an edit made between commits and a tile pruning removes.
// The walls of a cube of edge 2 * half around the origin: `count` x `count` points a face,
// `step` apart from the corner on.
std::vector<Eigen::Vector3f> cubeWalls(float half, int count, float step) {
  std::vector<Eigen::Vector3f> walls;
  for (int a = 0; a < count; ++a)
    for (int b = 0; b < count; ++b) {
      const float u = -half + step * static_cast<float>(a);
      const float v = -half + step * static_cast<float>(b);
      walls.insert(
          walls.end(),
          {{half, u, v}, {-half, u, v}, {u, half, v}, {u, -half, v}, {u, v, half}, {u, v, -half}});
    }
  return walls;
}

// Whether map `name` of `st` holds exactly `expected` (tilesOf's cut, in key order), tile for
// tile; the stored tiles, sorted, into `stored`.
::testing::AssertionResult storeHolds(store::Store& st, const std::string& name,
                                      const std::vector<store::Tile>& expected,
                                      std::vector<store::Tile>& stored) {
  stored = st.tiles(name, nullptr);
  std::sort(stored.begin(), stored.end(),
            [](const store::Tile& x, const store::Tile& y) { return x.key < y.key; });
  if (stored.size() != expected.size())
    return ::testing::AssertionFailure()
           << stored.size() << " tiles stored, " << expected.size() << " in the map";
  for (std::size_t i = 0; i < expected.size(); ++i)
    if (!(stored[i] == expected[i]))
      return ::testing::AssertionFailure() << "tile " << expected[i].key << " differs";
  return ::testing::AssertionSuccess();
}

TEST(StoreWriter, CommitsOnlyTheScansTilesYetHoldsTheWholeCut) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch("store");
  std::unique_ptr<store::Store> st = store::Store::open(scratch / "w.sqlite", true);
  MapParams params;
  params.resolution = 0.2;  // a tile is 3.2 m: a 25.6 m room's free middle merges above it
  store::MapWriter writer(*st, "w", params);
  OccupancyMap map(ctx, params);
  // The walls of a cube of edge 25.4 m around the sensor: rays through all of its middle.
  const std::vector<Eigen::Vector3f> walls = cubeWalls(12.7f, 64, 0.4f);
  std::size_t incremental = 0, above = 0, removed = 0;
  const auto commitAndCheck = [&](std::uint64_t scan) {
    const store::CommitStats stats = writer.commit(map, "test", scan);
    const std::vector<store::Tile> expected = store::tilesOf(map.download());
    std::vector<store::Tile> stored;
    ASSERT_TRUE(storeHolds(*st, "w", expected, stored)) << "after scan " << scan;
    if (stats.tiles_compared < expected.size()) ++incremental;
    for (const store::Tile& t : expected) above += store::tileKeyDepth(t.key) < store::kTileDepth;
    removed += stats.tiles_removed;
  };
  std::uint64_t scan = 0;
  const auto insert = [&](const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3f& at) {
    writer.begin(map);
    map.insertPointCloud(points, at);
    commitAndCheck(scan++);
  };
  for (int i = 0; i < 6; ++i)
    insert(walls, Eigen::Vector3f(0.05f * static_cast<float>(i), 0.0f, 0.0f));
  EXPECT_GT(above, 0u) << "no free region merged above the tile depth: the test misses its case";
  std::vector<Eigen::Vector3f> with_box = walls;
  for (int i = 0; i < 6; ++i)
    with_box.push_back({2.1f + 0.2f * static_cast<float>(i), -3.3f, 1.1f});  // an obstacle
  insert(with_box, Eigen::Vector3f(0.1f, 0.0f, 0.0f));
  writer.begin(map);
  map.clearBox(Eigen::Vector3f(-1.0f, -1.0f, -1.0f), Eigen::Vector3f(1.0f, 1.0f, 1.0f));  // an edit
  map.insertPointCloud(walls, Eigen::Vector3f(0.0f, 0.1f, 0.0f));
  commitAndCheck(scan++);
  // The obstacle gone: its cells fade to free and merge again (tiles removed).
  for (int i = 0; i < 3; ++i)
    insert(walls, Eigen::Vector3f(0.0f, 0.05f * static_cast<float>(i), 0.0f));
  EXPECT_GE(incremental, 4u) << "commits compared every tile: the scan's tiles were not used";
  EXPECT_GT(removed, 0u) << "no tile was removed: the test misses merging";
}

// Commits as integrate makes them: each scan's capture comes with its own submission, and its
// commit (finish) runs while the next scan is on the device. Scans of growing size make the
// device refuse some (the pool and sets grow, the scan runs again, its capture recorded again).
// After each commit the store holds the map as that scan left it: a map without a store, given
// the same scans one by one, says what that is.
TEST(StoreWriter, CommitsWhileTheNextScanRunsAndHoldsEachScansMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch("store");
  std::unique_ptr<store::Store> st = store::Store::open(scratch / "n.sqlite", true);
  MapParams params;
  params.resolution = 0.2;
  store::MapWriter writer(*st, "n", params);
  OccupancyMap map(ctx, params), reference(ctx, params);
  std::vector<std::vector<Eigen::Vector3f>> scans;
  std::vector<Eigen::Vector3f> origins;
  for (int i = 0; i < 8; ++i) {
    // A wall 2 m ahead of the sensor, which moves 4 m a scan: few tiles each; the fifth scan
    // sees the walls of a room around everything, many times the points (the device refuses
    // it at first).
    const float x = 4.0f * static_cast<float>(i);
    if (i == 4) {
      scans.push_back(cubeWalls(12.0f, 30, 0.8f));
    } else {
      std::vector<Eigen::Vector3f> wall;
      for (int a = 0; a < 20; ++a)
        for (int b = 0; b < 20; ++b)
          wall.emplace_back(x + 2.0f, -1.5f + 0.15f * static_cast<float>(a),
                            -1.5f + 0.15f * static_cast<float>(b));
      scans.push_back(std::move(wall));
    }
    origins.emplace_back(x, 0.05f * static_cast<float>(i), 0.0f);
  }
  std::vector<std::vector<store::Tile>> expected;
  std::size_t reruns = 0, incremental = 0;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    map.submitPointCloud(scans[i], origins[i]);
    reference.insertPointCloud(scans[i], origins[i]);
    expected.push_back(store::tilesOf(reference.download()));
    const store::CommitStats last = writer.finish();  // scan i - 1, while scan i runs
    if (i > 0) {
      std::vector<store::Tile> stored;
      ASSERT_TRUE(storeHolds(*st, "n", expected[i - 1], stored)) << "after scan " << i - 1;
      if (last.tiles_compared < expected[i - 1].size()) ++incremental;
    }
    ASSERT_FALSE(writer.begin(map));  // the only writer: nothing to load
    writer.commitInBackground(map, "test", i);
    for (const ScanStats& s : map.takeScanStats())
      reruns += s.ticket > 1 && s.cell_set_attempts > 1;  // a scan after the first commit
  }
  writer.finish();
  std::vector<store::Tile> stored;
  ASSERT_TRUE(storeHolds(*st, "n", expected.back(), stored));
  EXPECT_EQ(st->log("n").size(), scans.size());
  EXPECT_GT(reruns, 0u) << "no scan ran again: the test misses its case";
  EXPECT_GE(incremental, 3u) << "the commits compared every tile";
}

// The capture each scan brings (StoreAccess::captureScans) is, after the first, the scan's change
// applied to the host's copy of the pool (CaptureMirror): its tiles and upper stamps are the ones
// of the whole pool copied right after the scan, plain, colour and stamped. The scans revisit the
// same walls until their cells clamp (a clamped leaf changes no more), one is refused at first
// (a larger room: its capture is whole again), and a degrade between two scans (the tree changed
// otherwise) makes the next capture whole.
TEST(StoreCapture, EachScansChangeGivesTheTilesOfTheWholePool) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  for (const Payload kind : {Payload::kNone, Payload::kColor, Payload::kStamp}) {
    SCOPED_TRACE(treeTypeName(kind));
    MapParams params;
    params.resolution = 0.2;
    params.payload = kind;
    std::optional<ColorMap> color;
    std::optional<StampedMap> stamped;
    std::optional<OccupancyMap> plain;
    if (kind == Payload::kColor) color.emplace(ctx, params);
    if (kind == Payload::kStamp) stamped.emplace(ctx, params);
    if (kind == Payload::kNone) plain.emplace(ctx, params);
    OccupancyMap& map = color     ? static_cast<OccupancyMap&>(*color)
                        : stamped ? static_cast<OccupancyMap&>(*stamped)
                                  : *plain;
    StoreAccess::captureScans(map, store::kTileDepth);
    const std::vector<Eigen::Vector3f> small = cubeWalls(3.0f, 12, 0.3f);
    const std::vector<Eigen::Vector3f> large = cubeWalls(9.0f, 40, 0.6f);
    std::size_t from_change = 0, whole = 0, reruns = 0;
    for (std::uint32_t scan = 0; scan < 12; ++scan) {
      const std::vector<Eigen::Vector3f>& points = scan == 6 ? large : small;
      const Eigen::Vector3f origin(0.02f * static_cast<float>(scan % 3), 0.0f, 0.0f);
      const std::vector<Rgb> colors = test::colorsOf(scan, points.size());
      if (stamped && scan == 9) stamped->degradeOutdated(100 + scan, 2);
      ScanOptions options;
      if (color) options.colors = colors;
      if (stamped) options.stamp = 100 + scan;
      map.submitPointCloud(points, origin, options);
      const std::uint64_t ticket = StoreAccess::capturingTicket(map);
      ASSERT_NE(ticket, 0u) << "scan " << scan << " brought no capture";
      const std::optional<PoolCapture> taken = StoreAccess::takeCapture(map, ticket, 0);
      ASSERT_TRUE(taken.has_value()) << "scan " << scan;
      (taken->from_change ? from_change : whole) += 1;
      const PoolCapture copied = StoreAccess::capture(map, 0, store::kTileDepth);
      EXPECT_EQ(taken->root_exists, copied.root_exists);
      const std::vector<store::PoolTile> tiles = store::poolTiles(*taken);
      const std::vector<store::PoolTile> expected = store::poolTiles(copied);
      ASSERT_EQ(tiles.size(), expected.size()) << "scan " << scan;
      for (std::size_t i = 0; i < tiles.size(); ++i) {
        ASSERT_EQ(tiles[i].key, expected[i].key) << "scan " << scan;
        ASSERT_TRUE(store::poolTileBody(*taken, tiles[i]) ==
                    store::poolTileBody(copied, expected[i]))
            << "scan " << scan << ", tile " << tiles[i].key;
      }
      EXPECT_EQ(store::poolUpperStamps(*taken), store::poolUpperStamps(copied)) << "scan " << scan;
      for (const ScanStats& s : map.takeScanStats()) reruns += s.cell_set_attempts > 1;
    }
    EXPECT_GT(reruns, 0u) << "no scan ran again: the test misses its case";
    // The first, the refused one's, and (stamped) the one after the degrade are whole.
    EXPECT_GE(from_change, 8u);
    EXPECT_GE(whole, 2u);
  }
}

// A colour scan folds its colours into nodes off its updated paths: a leaf at the clamping bound
// takes no update (OctoMap's updateNode returns early), yet averageNodeColor changes its colour.
// The same room scanned again and again, committed after each scan, waited for and in the
// background: the store holds the map's cut every time (the fold's list names those tiles).
TEST(StoreWriter, ColoursOfClampedLeavesAreCommitted) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch("store");
  MapParams params;
  params.resolution = 0.2;
  params.payload = Payload::kColor;
  const std::vector<Eigen::Vector3f> room = cubeWalls(3.0f, 12, 0.3f);
  for (const bool background : {false, true}) {
    SCOPED_TRACE(background ? "in the background" : "waited for");
    const std::string location = scratch / (background ? "b.sqlite" : "w.sqlite");
    std::unique_ptr<store::Store> st = store::Store::open(location, true);
    store::MapWriter writer(*st, "c", params);
    ColorMap map(ctx, params);
    std::vector<std::vector<store::Tile>> expected;
    std::size_t all_clamped = 0;  // scans whose every cell was at the clamping bound already
    for (std::uint32_t scan = 0; scan < 10; ++scan) {
      const std::vector<Rgb> colors = test::colorsOf(scan, room.size());
      writer.begin(map);
      const ScanStats stats = map.insertPointCloud(room, Eigen::Vector3f(0, 0, 0), colors);
      all_clamped += stats.aborted_cells == stats.occupied_cells + stats.free_cells;
      expected.push_back(store::tilesOf(map.download()));
      std::vector<store::Tile> stored;
      if (!background) {
        writer.commit(map, "test", scan);
        ASSERT_TRUE(storeHolds(*st, "c", expected.back(), stored)) << "after scan " << scan;
        continue;
      }
      writer.commitInBackground(map, "test", scan);
      writer.finish();
      ASSERT_TRUE(storeHolds(*st, "c", expected.back(), stored)) << "after scan " << scan;
    }
    EXPECT_GE(all_clamped, 3u) << "no scan changed colours alone: the test misses its case";
  }
}

// A map larger than its cap, committed scan by scan while its working set spills tiles: long
// scans over a map the pool holds a third of run in groups of tiles and move tiles between their
// parts, so that some leave the device with changes no commit has seen (they come to the commit
// as dirty subtrees). After every commit the store holds the cut of the whole map (spilled tiles
// included), plain and colour.
TEST(StoreWriter, SpilledMapHoldsTheCutOfTheWholeMap) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch("store");
  for (const Payload kind : {Payload::kNone, Payload::kColor}) {
    SCOPED_TRACE(treeTypeName(kind));
    MapParams params;
    params.resolution = 0.1;
    params.payload = kind;
    const std::vector<Eigen::Vector3f> origins = {
        {0, 0, 0}, {0.35f, -0.25f, 0.15f}, {-0.3f, 0.2f, 0.1f}};
    std::size_t pool = 0, total = 0;
    {
      OccupancyMap probe(ctx, params);
      for (std::size_t i = 0; i < origins.size(); ++i)
        probe.insertPointCloud(test::sphere(6.0f + 0.5f * static_cast<float>(i), 2000, origins[i]),
                               origins[i]);
      pool = probe.poolBytes();
      total = probe.deviceBytes();
    }
    params.max_device_bytes = total - pool + pool / 3;
    const std::string path = scratch / (std::string(treeTypeName(kind)) + ".sqlite");
    std::unique_ptr<store::Store> st = store::Store::open(path, true);
    store::MapWriter writer(*st, "w", params);
    OccupancyMap map(ctx, params);
    map.spillTilesTo(makeHostTileSpill());
    std::size_t in_parts = 0;
    for (std::size_t i = 0; i < origins.size(); ++i) {
      const auto points = test::sphere(6.0f + 0.5f * static_cast<float>(i), 2000, origins[i]);
      writer.begin(map);
      const ScanStats stats =
          kind == Payload::kColor
              ? map.insertPointCloud(
                    points, origins[i],
                    {.colors = test::colorsOf(7 + static_cast<std::uint32_t>(i), points.size())})
              : map.insertPointCloud(points, origins[i]);
      in_parts += stats.tile_groups > 1;
      writer.commit(map, "test", i);
      std::vector<store::Tile> stored;
      ASSERT_TRUE(storeHolds(*st, "w", store::tilesOf(map.download()), stored)) << "scan " << i;
    }
    EXPECT_GT(in_parts, 0u) << "no scan ran in groups of tiles: the test misses its case";
    EXPECT_GT(map.spillCounts().evicted, 0u);
    EXPECT_LE(map.deviceBytes(), params.max_device_bytes);
  }
}

// A colour or stamped map committed scan by scan: the store holds exactly the cut of the device
// map after each commit (the incremental capture, colours averaged inside tiles, the stamps above
// the tile depth in their record), and the tree rebuilt from its tiles is OctoMap's ColorOcTree
// or OcTreeStamped doing the same steps (a degrade before the later stamped scans). Leaves above
// the tile depth: StoreTiles.PayloadTilesMergeAsOctoMapPrunes.
TEST(StoreWriter, ColourAndStampedMapsHoldTheirCutAndOctoMapsTree) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  Scratch scratch("store");
  // The walls of a cube of edge 12.7 m around the sensor.
  const std::vector<Eigen::Vector3f> walls = cubeWalls(6.35f, 24, 0.55f);
  for (const Payload kind : {Payload::kColor, Payload::kStamp}) {
    SCOPED_TRACE(treeTypeName(kind));
    const std::string location = scratch / (std::string(treeTypeName(kind)) + ".sqlite");
    std::unique_ptr<store::Store> st = store::Store::open(location, true);
    MapParams params;
    params.resolution = 0.2;
    params.payload = kind;
    store::MapWriter writer(*st, "w", params);
    EXPECT_EQ(st->map("w")->params.payload, kind);
    ColorMap color_map(ctx, params.payload == Payload::kColor ? params : MapParams{});
    std::optional<StampedMap> stamped;
    if (kind == Payload::kStamp) stamped.emplace(ctx, params);
    OccupancyMap& map = kind == Payload::kColor ? static_cast<OccupancyMap&>(color_map) : *stamped;
    std::unique_ptr<octomap::ColorOcTree> color_oracle = test::makeColorOracle(params);
    test::StampedOracle stamp_oracle(params);
    std::size_t incremental = 0;
    for (std::uint64_t scan = 0; scan < 5; ++scan) {
      // The room, then a small patch 3 m away (a commit of few tiles) with an obstacle in front
      // that later fades (stamped: degraded), the room again.
      std::vector<Eigen::Vector3f> points = walls;
      if (scan % 2 == 1) {
        points.clear();
        for (int i = 0; i < 100; ++i)
          points.push_back(
              {3.0f, 0.1f * static_cast<float>(i % 10), 0.1f * static_cast<float>(i / 10)});
        if (scan == 1)
          for (int i = 0; i < 6; ++i) points.push_back({2.0f, 0.1f * static_cast<float>(i), 0.3f});
      }
      const Eigen::Vector3f origin(0.05f * static_cast<float>(scan), 0.0f, 0.0f);
      const auto stamp = static_cast<std::uint32_t>(100 + 10 * scan);
      const std::vector<Rgb> colors = test::colorsOf(scan, points.size());
      writer.begin(map);
      if (kind == Payload::kColor) {
        color_map.insertPointCloud(points, origin, colors);
        color_oracle->insertPointCloud(test::toPointcloud(points), test::toPoint(origin));
        for (std::size_t i = 0; i < points.size(); ++i)
          color_oracle->averageNodeColor(points[i].x(), points[i].y(), points[i].z(), colors[i].r,
                                         colors[i].g, colors[i].b);
        color_oracle->updateInnerOccupancy();
      } else {
        if (scan >= 3) {
          stamped->degradeOutdated(stamp, 15);
          stamp_oracle.degradeOutdated(stamp, 15);
        }
        stamped->insertPointCloud(points, origin, stamp);
        stamp_oracle.setScanTime(stamp);
        stamp_oracle.insertPointCloud(test::toPointcloud(points), test::toPoint(origin));
      }
      const store::CommitStats stats = writer.commit(map, "test", scan);
      const std::vector<store::Tile> expected = store::tilesOf(map.download());
      std::vector<store::Tile> stored;
      ASSERT_TRUE(storeHolds(*st, "w", expected, stored)) << "after scan " << scan;
      if (stats.tiles_compared < expected.size()) ++incremental;
      const HostTree rebuilt = store::treeFromTiles(stored, store::kTileDepth, kind);
      if (kind == Payload::kColor)
        ASSERT_TRUE(test::samePayloadTree(*color_oracle, rebuilt, kind)) << "after scan " << scan;
      else
        ASSERT_TRUE(test::samePayloadTree(stamp_oracle, rebuilt, kind)) << "after scan " << scan;
      // The tiles of the rebuilt tree are the stored ones: inner stamps above the tile depth
      // included.
      EXPECT_TRUE(store::tilesOf(rebuilt) == expected) << "after scan " << scan;
    }
    EXPECT_GE(incremental, 2u) << "commits compared every tile: the scan's tiles were not used";
    // Opened with other parameters, the map keeps its own tree type; it reads back whole.
    MapParams plain = params;
    plain.payload = Payload::kNone;
    EXPECT_EQ(StoredMap::open(ctx, location, "w", plain).map().params().payload, kind);
    OccupancyMap read = readStoredMap(ctx, location, "w");
    EXPECT_EQ(read.params().payload, kind);
    EXPECT_TRUE(store::tilesOf(read.download()) == store::tilesOf(map.download()));
  }
}

// Sibling tiles written on their own (as two writers may leave them) merge above the tile depth as
// OctoMap's pruning merges them: ColorOcTree's pruneNode colour, OcTreeStamped's equal stamps.
TEST(StoreTiles, PayloadTilesMergeAsOctoMapPrunes) {
  const unsigned depth = 12;
  const auto record = [](float log_odds, std::uint32_t payload, Payload kind) {
    std::string body(store::recordBytes(kind), '\0');
    std::memcpy(body.data(), &log_odds, sizeof(float));
    for (std::size_t i = 0; i + 5 < body.size(); ++i)
      body[4 + i] = static_cast<char>((payload >> (8 * i)) & 0xFFu);
    return body;
  };
  for (const Payload kind : {Payload::kColor, Payload::kStamp}) {
    SCOPED_TRACE(treeTypeName(kind));
    // Two groups of 8 sibling leaf tiles, equal log-odds: the first merges; the second merges for
    // colour (which compares log-odds only) but not for stamps (one differs); a lone tile too.
    std::vector<store::Tile> tiles;
    const std::uint64_t parent_a = 0123, parent_b = 0456;
    for (std::uint64_t i = 0; i < 8; ++i) {
      const std::uint32_t a =
          kind == Payload::kColor
              ? (i == 3 ? 0x00FFFFFFu : packRgb(Rgb{std::uint8_t(30 * i), 7, 200}))
              : 500u;
      const std::uint32_t b = kind == Payload::kColor ? packRgb(Rgb{9, std::uint8_t(20 * i), 1})
                                                      : (i == 5 ? 501u : 500u);
      tiles.push_back({store::tileKey(depth, (parent_a << 3) | i), record(1.5f, a, kind)});
      tiles.push_back({store::tileKey(depth, (parent_b << 3) | i), record(-0.4f, b, kind)});
    }
    tiles.push_back({store::tileKey(depth, 07777),
                     record(0.85f, kind == Payload::kColor ? 0x00FFFFFFu : 3u, kind)});
    // A leaf above the tile depth (a region pruned whole): a tile of one record.
    tiles.push_back({store::tileKey(depth - 2, 0654),
                     record(-1.2f, kind == Payload::kColor ? packRgb(Rgb{1, 2, 3}) : 77u, kind)});
    const HostTree rebuilt = store::treeFromTiles(tiles, depth, kind);
    // OctoMap: the same leaves set at depth 12, prune(), updateInnerOccupancy().
    const auto keyOfPath = [](std::uint64_t path) {
      octomap::OcTreeKey key(0, 0, 0);
      for (unsigned level = 0; level < depth; ++level) {
        const unsigned slot = static_cast<unsigned>(path >> (3 * (depth - 1 - level))) & 7u;
        for (unsigned a = 0; a < 3; ++a)
          if (slot & (1u << a))
            key[a] = static_cast<octomap::key_type>(key[a] | (1u << (15 - level)));
      }
      return key;
    };
    const auto build = [&](auto& oracle, auto node) {
      for (const store::Tile& t : tiles) {
        float v;
        std::memcpy(&v, t.body.data(), sizeof(float));
        node.setLogOdds(v);
        std::uint32_t payload = 0;
        for (std::size_t i = 0; i + 5 < t.body.size(); ++i)
          payload |= std::uint32_t{static_cast<unsigned char>(t.body[4 + i])} << (8 * i);
        if constexpr (std::is_same_v<decltype(node), octomap::ColorOcTreeNode>) {
          const Rgb c = unpackRgb(payload);
          node.setColor(c.r, c.g, c.b);
        } else {
          node.setTimestamp(payload);
        }
        const unsigned d = store::tileKeyDepth(t.key);
        oracle.setLeaf(keyOfPath(((t.key >> 5) >> (3 * (16 - d))) << (3 * (depth - d))), d, node);
      }
      // OctoMap's prune() stops at the first level without a merge (depth 15 here): its pruneNode
      // on the parents instead, as updateNode's way back up calls it.
      for (const std::uint64_t parent : {parent_a, parent_b})
        oracle.pruneNode(oracle.search(keyOfPath(parent << 3), depth - 1));
      oracle.updateInnerOccupancy();
    };
    MapParams params;
    params.resolution = 0.1;
    if (kind == Payload::kColor) {
      octomap::ColorOcTree like(0.1);
      test::LeafBuilt<octomap::ColorOcTree> oracle(like);
      build(oracle, octomap::ColorOcTreeNode());
      EXPECT_TRUE(test::samePayloadTree(oracle, rebuilt, kind));
    } else {
      octomap::OcTreeStamped like(0.1);
      test::LeafBuilt<octomap::OcTreeStamped> oracle(like);
      build(oracle, octomap::OcTreeNodeStamped());
      EXPECT_TRUE(test::samePayloadTree(oracle, rebuilt, kind));
    }
  }
}

// integrate --stamps --degrade-after into a store, in two runs (the second continues the map):
// the export's .ot and its stamps (every node's, the inner ones above the tile depth included)
// are the in-core run's over both graphs, which tests/payload_cli_test.cpp checks against
// OctoMap's OcTreeStamped. A plain run into the stamped map is refused by name.
TEST(StoreCli, StampedMapWithDegradeContinuesAsTheInCoreRun) {
  Scratch scratch("store");
  const std::vector<GraphScan> a = roomScans(4, 0.0f), b = roomScans(3, 0.4f);
  std::vector<GraphScan> both = a;
  both.insert(both.end(), b.begin(), b.end());
  const std::string graph_a = scratch / "a.graph", graph_b = scratch / "b.graph",
                    graph_both = scratch / "both.graph";
  writeGraph(graph_a, a);
  writeGraph(graph_b, b);
  writeGraph(graph_both, both);
  std::ofstream(scratch / "a.stamps") << "100\n104\n109\n130\n";
  std::ofstream(scratch / "b.stamps") << "131\n150\n171\n";
  std::ofstream(scratch / "both.stamps") << "100\n104\n109\n130\n131\n150\n171\n";
  const std::string store = scratch / "s.sqlite";
  for (const char* part : {"a", "b"}) {
    const RunResult r = runOctovk({"integrate", scratch / (std::string(part) + ".graph"),
                                   "--stamps", scratch / (std::string(part) + ".stamps"),
                                   "--degrade-after", "12", "--store", store, "-r", "0.1", "-q"},
                                  scratch.dir());
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  }
  const RunResult direct =
      runOctovk({"integrate", graph_both, "--stamps", scratch / "both.stamps", "--degrade-after",
                 "12", "-r", "0.1", "-q", "-o", scratch / "direct.ot"},
                scratch.dir());
  ASSERT_EQ(direct.exit_code, 0) << direct.out << direct.err;
  const RunResult exported =
      runOctovk({"store", "export", store, "-o", scratch / "export.ot"}, scratch.dir());
  ASSERT_EQ(exported.exit_code, 0) << exported.out << exported.err;
  EXPECT_TRUE(readFile(scratch / "export.ot") == readFile(scratch / "direct.ot"));
  EXPECT_TRUE(readFile(scratch / "export.ot.stamps") == readFile(scratch / "direct.ot.stamps"));
  const RunResult info = runOctovk({"store", "info", store}, scratch.dir());
  EXPECT_NE(info.out.find("OcTreeStamped"), std::string::npos) << info.out;
  const RunResult plain = runOctovk({"integrate", graph_a, "--store", store, "-q"}, scratch.dir());
  test::expectOneErrorLine(plain, 2, {"OcTreeStamped", "--stamps"});
}

TEST(StoreCli, KilledWriterLeavesTheCommittedScans) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  Scratch scratch("store");
  expectKilledWriterLeavesItsLog(scratch / "map.sqlite", scratch);
}

}  // namespace
}  // namespace octovk

namespace octovk {
namespace {

// The back end itself: a commit whose sequence number is not the next one (another writer came
// first) is refused and writes nothing; a file that is no store is refused by name.
TEST(StoreBackEnd, StaleCommitIsRefusedAndWritesNothing) {
  Scratch scratch("store");
  const std::string path = scratch / "s.sqlite";
  auto store = store::Store::open(path, true);
  MapParams params;
  params.resolution = 0.2;
  store->createMap("m", params);
  const std::vector<store::Tile> one = {{store::tileKey(12, 5), std::string(5, '\0')}};
  store->commit("m", one, {}, {1, "a.graph", 0, 1});
  const std::vector<store::Tile> two = {{store::tileKey(12, 6), std::string(5, '\0')}};
  try {
    store->commit("m", two, {}, {1, "b.graph", 0, 2});  // seq 1 again: stale
    ADD_FAILURE() << "a stale commit was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("another writer"), std::string::npos) << e.what();
  }
  std::uint64_t seq = 0;
  EXPECT_EQ(store->tiles("m", &seq), one);
  EXPECT_EQ(seq, 1u);
  ASSERT_EQ(store->log("m").size(), 1u);
  EXPECT_EQ(store->map("m")->params.resolution, 0.2);
  store.reset();
  { std::ofstream(scratch / "empty.sqlite"); }
  EXPECT_THROW(store::Store::open(scratch / "empty.sqlite", false), Error);
  EXPECT_THROW(store::Store::open(scratch / "missing.sqlite", false), Error);
}

// The WAL's checkpoints run on a thread of their own beside the writer (sqlite_store.cpp's
// WalCheckpointer); the writer's own checkpoint of the rest must still let SQLite start the WAL
// over, though it holds the write lock from one commit to the next. 160 commits of 4 tiles of 100
// KB write about 4,800 frames of 16 KiB: a WAL that never starts over ended at 68 MB, one that
// does at 19 MB (1,000 frames and those committed while the thread worked). And nothing committed
// is lost, in the file after the writer closes.
TEST(StoreBackEnd, CheckpointsBesideTheWriterKeepTheWalSmall) {
  Scratch scratch("store");
  const std::string path = scratch / "s.sqlite";
  auto store = store::Store::open(path, true);
  store->createMap("m", MapParams{});
  std::mt19937 random(7);
  std::vector<store::Tile> last;
  constexpr int kCommits = 160;
  for (int c = 1; c <= kCommits; ++c) {
    // As MapWriter: the write lock held from before the scan to its commit, so that the WAL's
    // frames are all copied between two transactions only when the writer copied them.
    ASSERT_EQ(store->lock("m"), static_cast<std::uint64_t>(c - 1));
    last.clear();
    for (std::uint64_t t = 0; t < 4; ++t) {
      std::string body(100000, '\0');
      for (char& b : body) b = static_cast<char>(random());
      last.push_back({store::tileKey(12, t), std::move(body)});
    }
    store->commit("m", last, {}, {static_cast<std::uint64_t>(c), "a.graph", 0, c});
  }
  const std::uintmax_t wal = fs::file_size(path + "-wal");
  EXPECT_LT(wal, std::uintmax_t{40} << 20) << "the WAL did not start over";
  EXPECT_GT(wal, std::uintmax_t{1} << 20);  // the run did write through the WAL
  store.reset();
  EXPECT_FALSE(fs::exists(path + "-wal"));  // the last connection checkpointed and removed it
  auto reader = store::Store::open(path, false);
  std::uint64_t seq = 0;
  EXPECT_TRUE(reader->tiles("m", &seq) == last);
  EXPECT_EQ(seq, std::uint64_t{kCommits});
  EXPECT_EQ(reader->log("m").size(), std::size_t{kCommits});
}

}  // namespace
}  // namespace octovk

#ifdef OCTOVK_STORE_POSTGRES_TESTS
// Against a real PostgreSQL server, which tests/store_postgres.sh starts (its own binary: these
// tests are run only by that script, never skipped).
namespace octovk {
namespace {

std::string postgresUri() {
  const char* uri = std::getenv("OCTOVK_TEST_POSTGRES");
  return uri ? uri : "";
}

TEST(StorePostgres, IntegrateContinueAndExportAsGraph2tree) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  const std::string uri = postgresUri();
  ASSERT_FALSE(uri.empty()) << "run through tests/store_postgres.sh, which starts the server";
  Scratch scratch("store");
  const std::vector<GraphScan> a = roomScans(4, 0.0f), b = roomScans(3, 0.7f);
  const std::string graph_a = scratch / "a.graph", graph_b = scratch / "b.graph";
  writeGraph(graph_a, a);
  writeGraph(graph_b, b);
  const std::string map = "room" + std::to_string(::getpid());
  const RunResult first = runOctovk(
      {"integrate", graph_a, "--store", uri, "--map", map, "-r", "0.1", "-q"}, scratch.dir());
  ASSERT_EQ(first.exit_code, 0) << first.out << first.err;
  printStoreWrites(first.out);
  const std::string out_a = scratch / "a.ot";
  ASSERT_EQ(runOctovk({"store", "export", uri, "--map", map, "-o", out_a}, scratch.dir()).exit_code,
            0);
  EXPECT_EQ(readFile(out_a), graph2treeOt(graph_a, scratch));
  const RunResult second =
      runOctovk({"integrate", graph_b, "--store", uri, "--map", map, "-q"}, scratch.dir());
  ASSERT_EQ(second.exit_code, 0) << second.out << second.err;
  EXPECT_NE(second.out.find("(continued): 3 scans committed"), std::string::npos) << second.out;
  printStoreWrites(second.out);
  std::vector<GraphScan> both = a;
  both.insert(both.end(), b.begin(), b.end());
  writeGraph(scratch / "both.graph", both);
  const std::string out = scratch / "both.ot";
  ASSERT_EQ(runOctovk({"store", "export", uri, "--map", map, "-o", out}, scratch.dir()).exit_code,
            0);
  EXPECT_EQ(readFile(out), graph2treeOt(scratch / "both.graph", scratch));
  const RunResult log = runOctovk({"store", "log", uri, "--map", map}, scratch.dir());
  EXPECT_EQ(std::count(log.out.begin(), log.out.end(), '\n'), 7) << log.out;
  const RunResult info = runOctovk({"store", "info", uri}, scratch.dir());
  EXPECT_NE(info.out.find("(PostgreSQL)"), std::string::npos) << info.out;
  // A stale commit is refused there too, and writes nothing.
  auto store = store::Store::open(uri, false);
  const std::vector<store::Tile> tile = {{store::tileKey(12, 9), std::string(5, '\0')}};
  EXPECT_THROW(store->commit(map, tile, {}, {3, "x", 0, 0}), Error);
  EXPECT_EQ(store->log(map).size(), 7u);
  EXPECT_EQ(store->map(map)->last_seq, 7u);
}

TEST(StorePostgres, KilledWriterLeavesTheCommittedScans) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  ASSERT_FALSE(postgresUri().empty()) << "run through tests/store_postgres.sh";
  Scratch scratch("store");
  expectKilledWriterLeavesItsLog(postgresUri(), scratch);
}

TEST(StorePostgres, FollowerKeepsALocalCopyCurrent) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  ASSERT_FALSE(postgresUri().empty()) << "run through tests/store_postgres.sh";
  Scratch scratch("store");
  expectFollowerKeepsTheMap(postgresUri(), "follow" + std::to_string(::getpid()), scratch);
  // Told of each commit (LISTEN/NOTIFY): with an hour between looks it still follows at once.
  Scratch told("store-told");
  const auto start = std::chrono::steady_clock::now();
  expectFollowerKeepsTheMap(postgresUri(), "told" + std::to_string(::getpid()), told, "3600");
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(120));
}

// A commit that fails in the background (the server ends the writer's session while it holds
// the map's lock: another session calls pg_terminate_backend) is thrown by finish() naming the
// scan, and the store stays as after the scans before it (graph2tree's map of those).
TEST(StorePostgres, LostSessionFailsTheBackgroundCommitAndKeepsTheScansBefore) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  OCTOVK_REQUIRE_CONTEXT(ctx);
  ASSERT_FALSE(postgresUri().empty()) << "run through tests/store_postgres.sh";
  Scratch scratch("store");
  const std::vector<GraphScan> scans = roomScans(4, 0.0f);
  MapParams params;
  params.resolution = 0.1;
  {
    std::unique_ptr<store::Store> st = store::Store::open(postgresUri(), true);
    store::MapWriter writer(*st, "lost", params);
    OccupancyMap map(ctx, params);
    const auto insert = [&](std::size_t i) {
      writer.begin(map);
      std::vector<Eigen::Vector3f> world;
      for (const Eigen::Vector3f& p : scans[i].points_sensor)
        world.push_back(scans[i].T_world_sensor.transform(p));
      map.insertPointCloud(world, scans[i].T_world_sensor.translation);
    };
    for (std::size_t i = 0; i < 3; ++i) {
      insert(i);
      writer.commitInBackground(map, "lost", i);
    }
    insert(3);  // the lock is held now: the session is idle in its transaction
    const RunResult cut = runShell(
        "psql " + quote(postgresUri()) +
            " -qAt -c \"SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity WHERE "
            "datname = current_database() AND pid <> pg_backend_pid()\"",
        scratch.dir());
    ASSERT_EQ(cut.exit_code, 0) << cut.err;
    EXPECT_EQ(cut.out, "1\n") << "expected to end the writer's session alone";
    writer.commitInBackground(map, "lost", 3);
    try {
      writer.finish();
      ADD_FAILURE() << "the commit of a session the server ended succeeded";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kIo) << e.what();
      EXPECT_NE(std::string(e.what()).find("did not commit scan 3 of 'lost'"), std::string::npos)
          << e.what();
      std::cout << "[ lost     ] " << e.what() << "\n";
    }
  }
  auto store = store::Store::open(postgresUri(), false);
  ASSERT_EQ(store->log("lost").size(), 3u);
  const std::vector<GraphScan> kept(scans.begin(), scans.begin() + 3);
  const std::string graph = scratch / "kept.graph";
  writeGraph(graph, kept);
  const RunResult e =
      runOctovk({"store", "export", postgresUri(), "--map", "lost", "-o", scratch / "kept.ot"},
                scratch.dir());
  ASSERT_EQ(e.exit_code, 0) << e.err;
  EXPECT_TRUE(readFile(scratch / "kept.ot") == graph2treeOt(graph, scratch))
      << "the store is not the map of the three scans before the lost commit";
}

// The program's side of a lost session: `integrate --store` whose session the server ends
// mid-run (in a commit, or between two) stops with exit status 1 naming the first scan the
// store does not hold, and the store is graph2tree's map of the scans before it.
TEST(StorePostgres, LostSessionEndsTheRunNamingTheFirstScanNotCommitted) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  ASSERT_FALSE(postgresUri().empty()) << "run through tests/store_postgres.sh";
  Scratch scratch("store");
  const std::vector<GraphScan> scans = roomScans(400, 0.0f);
  const std::string graph = scratch / "long.graph";
  writeGraph(graph, scans);
  const std::string map = "cut";
  OctovkProcess writer(
      {"integrate", graph, "--store", postgresUri(), "--map", map, "-r", "0.1", "-q"},
      scratch.dir());
  ASSERT_TRUE(writer.started());
  const fs::path psql_dir = scratch.dir() / "psql";
  fs::create_directories(psql_dir);
  const bool some = pollUntil(
      [&] {
        try {
          auto store = store::Store::open(postgresUri(), false);
          return store->map(map) && store->log(map).size() >= 3;
        } catch (const Error&) {
          return false;  // not created yet
        }
      },
      std::chrono::seconds(120));
  const RunResult cut =
      runShell("psql " + quote(postgresUri()) +
                   " -qAt -c \"SELECT count(pg_terminate_backend(pid)) FROM pg_stat_activity WHERE "
                   "datname = current_database() AND pid <> pg_backend_pid()\"",
               psql_dir);  // not the writer's folder: its output files are there
  const RunResult r = writer.wait();
  ASSERT_TRUE(some) << r.out << r.err;
  ASSERT_EQ(cut.exit_code, 0) << cut.err;
  ASSERT_EQ(r.exit_code, 1) << "the run was not cut: " << r.out << r.err;
  auto store = store::Store::open(postgresUri(), false);
  const std::size_t committed = store->log(map).size();
  ASSERT_GE(committed, 3u);
  ASSERT_LT(committed, scans.size());
  std::cout << "[ cut      ] " << r.err;
  const std::string place = "scan " + std::to_string(committed + 1) + " of 400: ";
  EXPECT_NE(r.err.find(place), std::string::npos) << "expected '" << place << "': " << r.err;
  // In words, on one line (the session ended in a commit, or between two: then taking the
  // lock fails): what failed and the remedy, no SQL, no notice of the server's.
  test::expectOneErrorLine(r, 1, {"connection to the server is lost"});
  for (const char* raw : {"SELECT", "INSERT", "FATAL"})
    EXPECT_EQ(r.err.find(raw), std::string::npos) << raw << " in: " << r.err;
  const std::vector<GraphScan> kept(scans.begin(), scans.begin() + static_cast<long>(committed));
  const std::string graph_kept = scratch / "kept.graph";
  writeGraph(graph_kept, kept);
  const RunResult e = runOctovk(
      {"store", "export", postgresUri(), "--map", map, "-o", scratch / "kept.ot"}, scratch.dir());
  ASSERT_EQ(e.exit_code, 0) << e.err;
  EXPECT_TRUE(readFile(scratch / "kept.ot") == graph2treeOt(graph_kept, scratch))
      << "the store is not the map of the " << committed << " scans before the run was cut";
}

TEST(StorePostgres, TwoWritersAtOnceGiveTheMapOfTheLog) {
  OCTOVK_REQUIRE_GRAPH2TREE();
  ASSERT_FALSE(postgresUri().empty()) << "run through tests/store_postgres.sh";
  Scratch scratch("store");
  expectTwoWritersGiveTheLogsMap(postgresUri(), scratch);
}

}  // namespace
}  // namespace octovk
#endif
