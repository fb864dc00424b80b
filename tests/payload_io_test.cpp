// Files and conversions of maps with a payload (issue 29): ColorOcTree and OcTreeStamped .ot / .bt
// files against OctoMap's own writers and readers, the stamps sidecar, refusals of damaged files,
// and the CLI's info / export on a colour map. Trees are built with OctoMap directly.
//
// PayloadIoFiles: the file layer on its own (parse, host tree, OctoMap writer; no device).
// PayloadIoMap: through a map (upload / download carry the payload words).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "cli_support.hpp"
#include "io/parse.hpp"
#include "octovk/octomap_io.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

namespace fs = std::filesystem;

std::string payloadError(const std::function<void()>& call, ErrorCode code, const char* what) {
  try {
    call();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << what << ": " << e.what();
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << what << ": threw something else than octovk::Error: " << e.what();
    return {};
  }
  ADD_FAILURE() << what << ": no exception";
  return {};
}

float fl(int i) { return static_cast<float>(i); }

// Trees are built again rather than copied: OctoMap's tree copy makes the children plain data
// nodes (OcTreeDataNode's copy), losing a ColorOcTreeNode's colour.

// A small ColorOcTree as a scan and its colouring leave one: some leaves merged by prune(), colours
// on leaves (a few left white), inner values and colours from updateInnerOccupancy().
std::unique_ptr<octomap::ColorOcTree> colorTree() {
  auto tree = std::make_unique<octomap::ColorOcTree>(0.1);
  for (int x = 0; x < 6; ++x)
    for (int y = 0; y < 4; ++y)
      for (int z = 0; z < 3; ++z) {
        const octomap::point3d p(0.05f + 0.1f * fl(x), -0.35f + 0.1f * fl(y), 0.05f + 0.1f * fl(z));
        tree->updateNode(p, (x + y + z) % 3 != 0, /*lazy_eval=*/true);
        if ((x * 7 + y * 3 + z) % 5 != 0)
          tree->setNodeColor(p.x(), p.y(), p.z(), static_cast<std::uint8_t>(40 * x + 3),
                             static_cast<std::uint8_t>(50 * y + 7), static_cast<std::uint8_t>(z));
      }
  // A block of 8 equal leaves with different colours, which prune() merges (colour averaged).
  for (int i = 0; i < 8; ++i) {
    const octomap::point3d p(-0.75f + 0.1f * fl(i & 1), -0.75f + 0.1f * fl((i >> 1) & 1),
                             -0.75f + 0.1f * fl(i >> 2));
    tree->setNodeValue(p, 2.0f);
    tree->setNodeColor(p.x(), p.y(), p.z(), static_cast<std::uint8_t>(10 * i), 200, 100);
  }
  tree->updateInnerOccupancy();
  tree->prune();
  tree->updateInnerOccupancy();
  return tree;
}

// OctoMap's OcTreeStamped with node stamps set by hand: leaves of two ages, inner nodes stamped.
std::unique_ptr<octomap::OcTreeStamped> stampedTree() {
  auto tree = std::make_unique<octomap::OcTreeStamped>(0.1);
  for (int x = 0; x < 5; ++x)
    for (int y = 0; y < 3; ++y) {
      const octomap::point3d p(0.05f + 0.1f * fl(x), 0.05f + 0.1f * fl(y), 0.25f);
      octomap::OcTreeNodeStamped* n = tree->updateNode(p, (x + y) % 2 == 0, /*lazy_eval=*/true);
      n->setTimestamp(1000u + 17u * static_cast<unsigned>(x * 3 + y));
    }
  // Two blocks of 8 equal leaves: writeBinary's prune merges the first (equal stamps too), not
  // the second (one stamp each), as OcTreeNodeStamped::operator== decides.
  for (int block = 0; block < 2; ++block)
    for (int i = 0; i < 8; ++i) {
      const octomap::point3d p(-0.75f + 0.1f * fl(i & 1) + 0.4f * fl(block),
                               -0.75f + 0.1f * fl((i >> 1) & 1), -0.75f + 0.1f * fl(i >> 2));
      tree->setNodeValue(p, 2.0f, /*lazy_eval=*/true)
          ->setTimestamp(block == 0 ? 700u : 700u + static_cast<unsigned>(i));
    }
  tree->updateInnerOccupancy();
  std::uint32_t inner = 5;
  for (auto it = tree->begin_tree(), end = tree->end_tree(); it != end; ++it)
    if (!it.isLeaf()) it->setTimestamp(inner++);
  return tree;
}

template <class Tree>
std::string otOf(const Tree& tree) {
  std::stringstream s;
  tree.write(s);
  return s.str();
}

template <class Tree>
std::string btOf(Tree& tree) {
  std::stringstream s;
  tree.writeBinary(s);
  return s.str();
}

// Two trees' nodes, depth first: log-odds bits, shape and (for colour trees) colours equal.
template <class Tree>
::testing::AssertionResult sameNodes(const Tree& expected, const Tree& actual) {
  auto a = expected.begin_tree(), b = actual.begin_tree();
  const auto a_end = expected.end_tree(), b_end = actual.end_tree();
  std::size_t i = 0;
  for (; a != a_end && b != b_end; ++a, ++b, ++i) {
    if (a.getKey() != b.getKey() || a.getDepth() != b.getDepth())
      return ::testing::AssertionFailure() << "node " << i << ": at another place";
    if (test::floatBits(a->getLogOdds()) != test::floatBits(b->getLogOdds()))
      return ::testing::AssertionFailure()
             << "node " << i << ": log-odds " << a->getLogOdds() << " vs " << b->getLogOdds();
    if constexpr (std::is_same_v<Tree, octomap::ColorOcTree>) {
      if (a->getColor() != b->getColor())
        return ::testing::AssertionFailure()
               << "node " << i << ": colour " << a->getColor() << " vs " << b->getColor();
    }
  }
  if ((a == a_end) != (b == b_end))
    return ::testing::AssertionFailure() << "node counts differ after " << i;
  return ::testing::AssertionSuccess();
}

// Two files' bytes equal; else where they first differ (not both files printed whole).
::testing::AssertionResult sameBytes(const std::string& expected, const std::string& actual) {
  if (expected == actual) return ::testing::AssertionSuccess();
  std::size_t i = 0;
  while (i < expected.size() && i < actual.size() && expected[i] == actual[i]) ++i;
  return ::testing::AssertionFailure() << "sizes " << expected.size() << " and " << actual.size()
                                       << ", first difference at byte " << i;
}

template <class Tree>
const Tree& as(const io::AnyTree& any) {
  const auto* tree = std::get_if<std::unique_ptr<Tree>>(&any);
  if (!tree || !*tree) throw std::runtime_error("parsed as another tree type");
  return **tree;
}

// The host tree of an OctoMap tree, as readMapFile and fromColorOcTree make it.
template <class Tree>
HostTree hostOf(const Tree& tree) {
  std::stringstream s;
  tree.write(s);
  const std::string bytes = s.str();
  return io::hostTreeOf(io::parseTreeFile(bytes, false, "tree.ot"));
}

MapParams params01() {
  MapParams p;
  p.resolution = 0.1;
  return p;
}

// ---- the file layer ----

TEST(PayloadIoFiles, ColorOtAndBtReadAsOctoMapWroteThem) {
  const std::unique_ptr<octomap::ColorOcTree> tree = colorTree();
  const std::string ot = otOf(*tree);
  ASSERT_NE(ot.find("\nid ColorOcTree\n"), std::string::npos);
  const io::AnyTree read = io::parseTreeFile(ot, false, "color.ot");
  ASSERT_EQ(read.index(), 1u);
  EXPECT_TRUE(sameNodes(*tree, as<octomap::ColorOcTree>(read)));

  const std::string bt = btOf(*colorTree());
  ASSERT_NE(bt.find("\nid ColorOcTree\n"), std::string::npos);  // OctoMap names the type in .bt
  octomap::ColorOcTree theirs(0.1);
  std::stringstream in(bt);
  ASSERT_TRUE(theirs.readBinary(in));
  const io::AnyTree read_bt = io::parseTreeFile(bt, true, "color.bt");
  ASSERT_EQ(read_bt.index(), 1u);
  EXPECT_TRUE(sameNodes(theirs, as<octomap::ColorOcTree>(read_bt)));
}

TEST(PayloadIoFiles, StampedOtReadsAsOcTreeStamped) {
  const std::unique_ptr<octomap::OcTreeStamped> tree = stampedTree();
  const std::string ot = otOf(*tree);
  ASSERT_NE(ot.find("\nid OcTreeStamped\n"), std::string::npos);
  const io::AnyTree read = io::parseTreeFile(ot, false, "stamped.ot");
  ASSERT_EQ(read.index(), 2u);
  EXPECT_TRUE(sameNodes(*tree, as<octomap::OcTreeStamped>(read)));
  const HostTree host = io::hostTreeOf(read);
  EXPECT_EQ(host.payload, Payload::kStamp);
}

// What writeMapFile writes for a map whose download is `host`: OctoMap's bytes of the same tree.
TEST(PayloadIoFiles, WrittenTreeIsByteIdenticalToOctoMaps) {
  {
    const std::unique_ptr<octomap::ColorOcTree> tree = colorTree();
    const HostTree host = hostOf(*tree);
    ASSERT_EQ(host.payload, Payload::kColor);
    auto ours = io::octomapTreeOf(host, params01());
    std::stringstream ot;
    ours->write(ot);
    EXPECT_TRUE(sameBytes(otOf(*tree), ot.str()));
    std::stringstream bt;
    ours->writeBinary(bt);
    EXPECT_TRUE(sameBytes(btOf(*colorTree()), bt.str()));
  }
  {
    const std::unique_ptr<octomap::OcTreeStamped> tree = stampedTree();
    const HostTree host = io::hostTreeOf(io::AnyTree(stampedTree()));
    auto ours = io::octomapTreeOf(host, params01());
    EXPECT_EQ(ours->getTreeType(), "OcTreeStamped");
    // The stamps reached OctoMap's nodes.
    const auto& built = dynamic_cast<const octomap::OcTreeStamped&>(*ours);
    auto a = tree->begin_tree();
    for (auto b = built.begin_tree(); b != built.end_tree(); ++a, ++b)
      ASSERT_EQ(a->getTimestamp(), b->getTimestamp());
    std::stringstream ot;
    ours->write(ot);
    EXPECT_TRUE(sameBytes(otOf(*tree), ot.str()));
    std::stringstream bt;
    ours->writeBinary(bt);  // prunes where stamps are equal too
    EXPECT_TRUE(sameBytes(btOf(*stampedTree()), bt.str()));
    // Without the stamps, the second block would merge: another .bt.
    HostTree unstamped = host;
    for (HostTree::Node& n : unstamped.nodes) n.payload = 0;
    std::stringstream other;
    io::octomapTreeOf(unstamped, params01())->writeBinary(other);
    EXPECT_NE(other.str(), bt.str());
  }
}

TEST(PayloadIoFiles, MessageBodiesOfColorTreesAreRead) {
  const std::unique_ptr<octomap::ColorOcTree> tree = colorTree();
  std::stringstream full;
  tree->writeData(full);
  const std::string body = full.str();
  const io::AnyTree read = io::parseTreeBody(body, false, "ColorOcTree", 0.1, "msg");
  EXPECT_TRUE(sameNodes(*tree, as<octomap::ColorOcTree>(read)));
  // The same bytes named OcTree are 7-byte records read as 5: refused, not misread.
  const std::string why =
      payloadError([&] { (void)io::parseTreeBody(body, false, "OcTree", 0.1, "msg"); },
                   ErrorCode::kFormat, "colour body as OcTree");
  EXPECT_NE(why.find("'msg'"), std::string::npos) << why;
}

TEST(PayloadIoFiles, DamagedColorFilesAreRefused) {
  const std::unique_ptr<octomap::ColorOcTree> tree = colorTree();
  const std::string ot = otOf(*tree);
  const std::size_t data = ot.find("\ndata\n") + 6;
  const auto refused = [&](const std::string& bytes, const std::string& why, const char* what) {
    const std::string message = payloadError(
        [&] { (void)io::parseTreeFile(bytes, false, "damaged.ot"); }, ErrorCode::kFormat, what);
    EXPECT_NE(message.find("'damaged.ot'"), std::string::npos) << what << ": " << message;
    EXPECT_NE(message.find(why), std::string::npos) << what << ": " << message;
  };
  // Cut inside the first record's colour bytes.
  refused(ot.substr(0, data + 5), "runs past the end", "cut in a colour");
  // The root's log-odds made NaN.
  std::string nan = ot;
  const float bad = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan.data() + data, &bad, sizeof(bad));
  refused(nan, "not a finite number", "NaN log-odds");
  // A colour file named OcTree: its records do not line up as 5-byte ones.
  std::string relabelled = ot;
  relabelled.replace(relabelled.find("id ColorOcTree"), 14, "id OcTree");
  refused(relabelled, "", "ColorOcTree read as OcTree");
  // An OcTree file named ColorOcTree: as 7-byte records it does not hold its announced tree.
  octomap::OcTree plain(0.1);
  for (int i = 0; i < 20; ++i) plain.updateNode(octomap::point3d(0.1f * fl(i), 0.05f, 0.05f), true);
  std::string as_color = test::otBytes(plain);
  as_color.replace(as_color.find("id OcTree"), 9, "id ColorOcTree");
  refused(as_color, "", "OcTree read as ColorOcTree");
  // A record child byte flipped deep inside the data.
  std::string flipped = ot;
  flipped[data + 7] = static_cast<char>(0xFF);
  refused(flipped, "", "child byte");
}

TEST(PayloadIoFiles, StampsSidecarRoundTripsAndRefusesWhatIsNotItsTree) {
  const std::unique_ptr<octomap::OcTreeStamped> tree = stampedTree();
  const HostTree stamped = io::hostTreeOf(io::AnyTree(stampedTree()));
  const std::string sidecar = io::stampsFile(stamped);
  ASSERT_EQ(sidecar.size(), io::stampsFileSize(tree->size()));
  EXPECT_EQ(sidecar.substr(0, 8), "OVKSTAMP");

  HostTree read = hostOf(*tree);  // from the .ot: every stamp 0
  std::size_t nonzero = 0;
  for (const HostTree::Node& n : read.nodes) nonzero += n.payload != 0;
  EXPECT_EQ(nonzero, 0u);
  io::applyStampsFile(sidecar, read, "map.ot.stamps");
  ASSERT_EQ(read.nodes.size(), stamped.nodes.size());
  for (std::size_t i = 0; i < read.nodes.size(); ++i)
    EXPECT_EQ(read.nodes[i].payload, stamped.nodes[i].payload) << "node " << i;

  const auto refused = [&](const std::string& bytes, const HostTree& target, const std::string& why,
                           const char* what) {
    HostTree copy = target;
    const std::string message = payloadError(
        [&] { io::applyStampsFile(bytes, copy, "map.ot.stamps"); }, ErrorCode::kFormat, what);
    EXPECT_NE(message.find("'map.ot.stamps'"), std::string::npos) << what << ": " << message;
    EXPECT_NE(message.find(why), std::string::npos) << what << ": " << message;
    EXPECT_NE(message.find("delete it"), std::string::npos) << what << ": " << message;
    for (std::size_t i = 0; i < copy.nodes.size(); ++i)
      ASSERT_EQ(copy.nodes[i].payload, target.nodes[i].payload) << what << ": changed";
  };
  const HostTree zero = hostOf(*tree);
  refused(sidecar.substr(0, 20), zero, "shorter than the 32-byte header", "short");
  refused("XVKSTAMP" + sidecar.substr(8), zero, "does not start with 'OVKSTAMP'", "magic");
  std::string v2 = sidecar;
  v2[8] = 2;
  refused(v2, zero, "version 2", "version");
  refused(sidecar.substr(0, sidecar.size() - 4), zero, "bytes, not the", "a stamp short");
  refused(sidecar + "x", zero, "bytes, not the", "a byte more");
  std::string count = sidecar;
  count[16] = static_cast<char>(count[16] + 1);
  refused(count, zero, "stamps for", "node count");
  // Another tree of the same node count: one leaf's log-odds changed.
  const std::unique_ptr<octomap::OcTreeStamped> other = stampedTree();
  other->begin_leafs()->setLogOdds(other->begin_leafs()->getLogOdds() + 0.25f);
  refused(sidecar, hostOf(*other), "digest", "another tree");
}

// ---- through a map (upload and download carry the payload) ----

std::string tmpFile(const std::string& name) {
  const std::string path = test::tmpPath("payload_io_" + name);
  fs::remove(path);
  fs::remove(path + ".stamps");
  return path;
}

TEST(PayloadIoMap, ColorMapWritesOctoMapsBytesAndReadsThemBack) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::unique_ptr<octomap::ColorOcTree> tree = colorTree();
  ColorMap map(ctx, params01());
  fromColorOcTree(map, *tree);
  const std::string ot = tmpFile("color.ot"), bt = tmpFile("color.bt");
  writeMapFile(map, ot);
  writeMapFile(map, bt);
  EXPECT_TRUE(sameBytes(otOf(*tree), test::fileBytes(ot)));
  EXPECT_TRUE(sameBytes(btOf(*colorTree()), test::fileBytes(bt)));
  EXPECT_FALSE(fs::exists(ot + ".stamps"));
  EXPECT_TRUE(sameNodes(*tree, *toColorOcTree(map)));

  // OctoMap's file read back: a colour map with OctoMap's nodes and colours.
  test::writeBytes(ot, otOf(*tree));
  OccupancyMap read = readMapFile(ctx, ot);
  ASSERT_EQ(read.params().payload, Payload::kColor);
  ColorMap color(std::move(read));
  EXPECT_TRUE(sameNodes(*tree, *toColorOcTree(color)));
  const MapMessage full = fullMapToMessage(color);
  EXPECT_EQ(full.id, "ColorOcTree");
  std::stringstream data;
  tree->writeData(data);
  EXPECT_TRUE(sameBytes(data.str(), std::string(full.data.begin(), full.data.end())));
  OccupancyMap from_message = messageToMap(ctx, full);
  ASSERT_EQ(from_message.params().payload, Payload::kColor);
  ColorMap color_message(std::move(from_message));
  EXPECT_TRUE(sameNodes(*tree, *toColorOcTree(color_message)));

  // A ColorOcTree .bt holds no colours: a colour map, every colour white.
  test::writeBytes(bt, btOf(*colorTree()));
  OccupancyMap from_bt = readMapFile(ctx, bt);
  EXPECT_EQ(from_bt.params().payload, Payload::kColor);
  for (const HostTree::Node& n : from_bt.download().nodes)
    ASSERT_EQ(n.payload, packRgb(Rgb{})) << "a colour read from a .bt";
}

TEST(PayloadIoMap, StampedMapWritesItsStampsBesideTheOt) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::unique_ptr<octomap::OcTreeStamped> tree = stampedTree();
  StampedMap map(ctx, params01());
  fromOcTreeStamped(map, *tree);
  const std::string ot = tmpFile("stamped.ot"), bt = tmpFile("stamped.bt");
  writeMapFile(map, ot);
  writeMapFile(map, bt);
  EXPECT_TRUE(sameBytes(otOf(*tree), test::fileBytes(ot)));
  EXPECT_TRUE(sameBytes(btOf(*stampedTree()), test::fileBytes(bt)));
  ASSERT_TRUE(fs::exists(ot + ".stamps"));
  EXPECT_FALSE(fs::exists(bt + ".stamps"));
  EXPECT_TRUE(test::temporariesIn(fs::path(ot).parent_path()).empty());

  StampedMap read(readMapFile(ctx, ot));
  const std::unique_ptr<octomap::OcTreeStamped> back = toOcTreeStamped(read);
  EXPECT_TRUE(sameNodes(*tree, *back));
  auto a = tree->begin_tree();
  for (auto b = back->begin_tree(); b != back->end_tree(); ++a, ++b)
    ASSERT_EQ(a->getTimestamp(), b->getTimestamp());

  // The stream writer the program's outputs use: the same bytes and sidecar.
  std::ostringstream stream;
  std::string sidecar;
  EXPECT_EQ(writeMapStream(map, stream, /*binary=*/false, &sidecar), tree->size());
  EXPECT_TRUE(sameBytes(test::fileBytes(ot), stream.str()));
  EXPECT_EQ(sidecar, test::fileBytes(ot + ".stamps"));

  // info gives the leaves' oldest and newest stamps, from the sidecar.
  std::uint32_t oldest = ~0u, newest = 0;
  for (auto it = tree->begin_leafs(); it != tree->end_leafs(); ++it) {
    oldest = std::min(oldest, it->getTimestamp());
    newest = std::max(newest, it->getTimestamp());
  }
  const test::RunResult info = test::runOctovk({"info", ot}, fs::path(ot).parent_path());
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("OcTreeStamped"), std::string::npos) << info.out;
  EXPECT_NE(
      info.out.find("oldest " + std::to_string(oldest) + ", newest " + std::to_string(newest)),
      std::string::npos)
      << info.out;

  // A message holds no stamps: read back as a stamped map, stamps 0.
  const MapMessage full = fullMapToMessage(map);
  EXPECT_EQ(full.id, "OcTreeStamped");
  OccupancyMap from_message = messageToMap(ctx, full);
  EXPECT_EQ(from_message.params().payload, Payload::kStamp);
  EXPECT_EQ(from_message.nodeCount(), tree->size());
}

TEST(PayloadIoMap, StampedOtWithoutSidecarReadsWithStampsZero) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::unique_ptr<octomap::OcTreeStamped> tree = stampedTree();
  const std::string ot = tmpFile("octomap_stamped.ot");
  test::writeBytes(ot, otOf(*tree));  // OctoMap's file: no sidecar
  OccupancyMap read = readMapFile(ctx, ot);
  EXPECT_EQ(read.params().payload, Payload::kStamp);
  const HostTree host = read.download();
  EXPECT_EQ(host.payload, Payload::kStamp);
  for (const HostTree::Node& n : host.nodes) EXPECT_EQ(n.payload, 0u);
  EXPECT_EQ(read.nodeCount(), tree->size());
}

TEST(PayloadIoMap, DamagedColorFileAndBadSidecarAreRefusedByReadMapFile) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  const std::unique_ptr<octomap::ColorOcTree> color = colorTree();
  const std::string cut = tmpFile("cut_color.ot");
  const std::string ot = otOf(*color);
  test::writeBytes(cut, ot.substr(0, ot.size() - 3));
  std::string message =
      payloadError([&] { (void)readMapFile(ctx, cut); }, ErrorCode::kFormat, "cut colour file");
  EXPECT_NE(message.find("'" + cut + "'"), std::string::npos) << message;

  const std::unique_ptr<octomap::OcTreeStamped> stamped = stampedTree();
  const std::string path = tmpFile("bad_sidecar.ot");
  test::writeBytes(path, otOf(*stamped));
  test::writeBytes(path + ".stamps", "OVKSTAMP and then nothing useful");
  message = payloadError([&] { (void)readMapFile(ctx, path); }, ErrorCode::kFormat, "bad sidecar");
  EXPECT_NE(message.find("'" + path + ".stamps'"), std::string::npos) << message;
  EXPECT_NE(message.find("delete it"), std::string::npos) << message;
}

// ---- the CLI on a colour map ----

TEST(PayloadIoCli, InfoNamesTheTreeTypeAndExportWritesColours) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  const std::unique_ptr<octomap::ColorOcTree> tree = colorTree();
  const std::string ot = tmpFile("cli_color.ot");
  test::writeBytes(ot, otOf(*tree));
  const fs::path dir = fs::path(ot).parent_path();
  const test::RunResult info = test::runOctovk({"info", ot}, dir);
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("ColorOcTree"), std::string::npos) << info.out;
  std::size_t leaves = 0, coloured = 0;
  for (auto it = tree->begin_leafs(); it != tree->end_leafs(); ++it) {
    ++leaves;
    coloured += it->isColorSet();
  }
  EXPECT_NE(info.out.find(std::to_string(coloured) + " of " + std::to_string(leaves) +
                          " leaves with a colour"),
            std::string::npos)
      << info.out;

  const std::string ply = tmpFile("cli_color.ply");
  const test::RunResult exported = test::runOctovk({"export", ot, "-o", ply}, dir);
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  const std::string text = test::fileBytes(ply);
  EXPECT_NE(text.find("property uchar red\nproperty uchar green\nproperty uchar blue\n"),
            std::string::npos);
  // Every leaf's own colour, as OctoMap holds it: the vertex lines end in "r g b".
  std::size_t found = 0;
  for (auto it = tree->begin_leafs(); it != tree->end_leafs(); ++it) {
    const octomap::ColorOcTreeNode::Color c = it->getColor();
    std::ostringstream end;
    end << ' ' << int(c.r) << ' ' << int(c.g) << ' ' << int(c.b) << '\n';
    found += text.find(end.str()) != std::string::npos;
  }
  EXPECT_EQ(found, leaves);
  EXPECT_NE(text.find("colour: the map's (ColorOcTree)"), std::string::npos);
}

}  // namespace
}  // namespace octovk
