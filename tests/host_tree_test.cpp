// The tree between its device form and HostTree (map/host_tree.cpp), on the host alone: no
// device, so these run even where Vulkan does not.
#include "map/host_tree.hpp"

#include <gtest/gtest.h>

namespace octovk {
namespace {

// A root with children 1 and 6; child 6 has children 0 and 7; blocks: 0 root, 1 root's children,
// 2 unused, 3 child 6's children.
HostTree smallTree() {
  HostTree t;
  t.root_exists = true;
  t.nodes.assign(4 * 8, HostTree::Node{0.0f, gpu::kNoBlock, 0});
  t.nodes[0] = {0.5f, 1, (1u << 1) | (1u << 6)};
  t.nodes[8 + 1] = {-0.4f, gpu::kNoBlock, 0};
  t.nodes[8 + 6] = {0.85f, 3, (1u << 0) | (1u << 7)};
  t.nodes[3 * 8 + 0] = {0.85f, gpu::kNoBlock, 0};
  t.nodes[3 * 8 + 7] = {-2.0f, gpu::kNoBlock, 0};
  return t;
}

TEST(HostTree, PoolImageAndBackGiveTheSameTree) {
  const HostTree tree = smallTree();
  const PoolImage image = poolImageFromTree(tree);
  EXPECT_EQ(image.blocks, 4u);
  EXPECT_EQ(image.live_nodes, 5u);  // root, 2 children, 2 grandchildren
  EXPECT_TRUE(image.root_exists);
  ASSERT_EQ(image.free_blocks, std::vector<std::uint32_t>{2u});  // nothing points at block 2
  EXPECT_EQ(image.parents[1], 0u);
  EXPECT_EQ(image.parents[3], 8u + 6u);
  EXPECT_EQ(image.nodes[0].link, 1u | gpu::kFlagLive);
  EXPECT_EQ(image.nodes[8 + 2].link & gpu::kFlagLive, 0u);  // a slot no one uses is not live

  gpu::PoolState pool{};
  pool.bump = image.blocks;
  pool.root_exists = 1;
  const HostTree back = hostTreeFromPool(image.nodes, image.payload, tree.payload, pool);
  ASSERT_EQ(back.nodes.size(), tree.nodes.size());
  for (std::uint32_t n : {0u, 8u + 1u, 8u + 6u, 3u * 8u, 3u * 8u + 7u}) {
    EXPECT_EQ(back.nodes[n].log_odds, tree.nodes[n].log_odds) << "node " << n;
    EXPECT_EQ(back.nodes[n].mask, tree.nodes[n].mask) << "node " << n;
    if (tree.nodes[n].mask) {
      EXPECT_EQ(back.nodes[n].children, tree.nodes[n].children) << "node " << n;
    }
  }
}

TEST(HostTree, MalformedTreesAreRefusedNamingTheFault) {
  auto refused = [](const HostTree& t, const std::string& names) {
    try {
      poolImageFromTree(t);
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kFormat);
      EXPECT_NE(std::string(e.what()).find(names), std::string::npos) << e.what();
      return;
    }
    ADD_FAILURE() << "accepted a tree with " << names;
  };
  HostTree shared = smallTree();
  shared.nodes[8 + 1] = {0.1f, 3, 1u};  // block 3 hung under two nodes
  refused(shared, "shared by two nodes");
  HostTree outside = smallTree();
  outside.nodes[8 + 6].children = 9;
  refused(outside, "outside its nodes");
  HostTree root_block = smallTree();
  root_block.nodes[8 + 6].children = 0;  // block 0 holds the root: nobody's children
  refused(root_block, "outside its nodes");
  HostTree empty;
  empty.root_exists = true;
  refused(empty, "no root node");
  // A chain 17 levels deep: below OctoMap's 16.
  HostTree deep;
  deep.root_exists = true;
  deep.nodes.assign(18 * 8, HostTree::Node{0.0f, gpu::kNoBlock, 0});
  for (std::uint32_t level = 0; level <= 16; ++level) {
    const std::uint32_t node = level == 0 ? 0u : level * 8u;
    deep.nodes[node] = {0.0f, level + 1, 1u};
  }
  refused(deep, "below depth 16");
}

TEST(HostTree, EmptyMapHasNoRootAndOneBlock) {
  const PoolImage image = poolImageFromTree(HostTree{});
  EXPECT_EQ(image.blocks, 1u);
  EXPECT_FALSE(image.root_exists);
  EXPECT_EQ(image.live_nodes, 0u);
  EXPECT_TRUE(image.free_blocks.empty());
}

}  // namespace
}  // namespace octovk
