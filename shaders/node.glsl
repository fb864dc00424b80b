// A node of the pool, and the one place that reads or writes NODES: its link word (the block of
// its children and the kFlag* bits, the tree's shape) and its data (its log-odds). A payload
// (OctoMap's ColorOcTree colour, OcTreeStamped time stamp) joins the data here: NodeData, the
// functions under "the node's data" and its binding; no pass names a node's fields.
#ifndef OCTOVK_NODE_GLSL
#define OCTOVK_NODE_GLSL

#include "bindings.glsl"

// ---- the link word ----

// Node n's link word. Read atomically: classify prepares child slots and the descent and the
// prune pass set flags while other invocations search through the same nodes.
// A pass that writes no node (OCTOVK_NODES_READ_ONLY, defined before including this file) has no
// racing writer and reads links plainly.
#ifdef OCTOVK_NODES_READ_ONLY
uint linkOf(uint n) { return NODES[n].link; }
#else
uint linkOf(uint n) { return OCTOVK_LOAD(NODES[n].link); }
#endif

// Node n's link word where no other invocation of the dispatch writes it (the caller says why):
// a plain read.
uint settledLinkOf(uint n) { return NODES[n].link; }

// The block of node n's children, or kNoChildren.
uint childBlock(uint n) { return linkOf(n) & kBlockMask; }

// A link word's node exists / has children / is a leaf that exists.
bool linkLive(uint link) { return (link & kFlagLive) != 0u; }
bool linkHasChildren(uint link) { return (link & kBlockMask) != kNoChildren; }
bool linkLiveLeaf(uint link) { return linkLive(link) && !linkHasChildren(link); }

// Writes of a link word: plain where one invocation owns the word in the dispatch, atomic where
// others read or write it meanwhile (each pass says which).
void setLink(uint n, uint link) { NODES[n].link = link; }
void clearLinkBits(uint n, uint bits) { NODES[n].link &= ~bits; }
uint atomicOrLink(uint n, uint bits) { return atomicOr(NODES[n].link, bits); }
void atomicSetLink(uint n, uint link) { atomicExchange(NODES[n].link, link); }

// ---- the node's data ----

// What a node holds besides its link. Every copy, comparison and creation of a node's data goes
// through the functions below, so that a payload is one more field here and in them.
struct NodeData {
  float log_odds;
};

// OctoMap's getLogOdds / isNodeOccupied, for the passes that need no more of the data.
float nodeLogOdds(uint n) { return NODES[n].log_odds; }
bool nodeOccupied(uint n) { return nodeLogOdds(n) >= params.occupancy_log; }

NodeData nodeData(uint n) { return NodeData(NODES[n].log_odds); }
void setNodeData(uint n, NodeData d) { NODES[n].log_odds = d.log_odds; }

// The data of a node OctoMap creates (the root, createNodeChild): log-odds 0.
NodeData newNodeData() { return NodeData(0.0); }

// setLogOdds alone (clear_box's leaves take the lower clamping bound): a payload is kept.
void setNodeLogOdds(uint n, float log_odds) { NODES[n].log_odds = log_odds; }

// updateNodeLogOdds at a leaf of the scan: it takes `log_odds` (already clamped), the update's
// new value.
void setUpdatedLeaf(uint n, float log_odds) { NODES[n].log_odds = log_odds; }

// isNodeCollapsible's test of a child's data against the first child's: the same log-odds.
bool collapsibleData(NodeData first, NodeData child) { return child.log_odds == first.log_odds; }

// The block of a node's children as updateNodeRecurs meets it going up, read plainly (the caller
// says why nothing writes it in the dispatch): whether pruneNode merges it (isNodeCollapsible:
// all 8 children exist, have no children and hold collapsible data), and the data the node takes
// when it keeps it (updateOccupancyChildren: the maximum log-odds of the live children,
// getMaxChildLogOdds from -FLT_MAX). One pass over the block.
NodeData summariseChildren(uint block, out bool collapsible) {
  NodeData first = nodeData(block * 8u);
  float max_log_odds = -3.402823466e+38;
  collapsible = true;
  for (uint s = 0u; s < 8u; ++s) {
    uint child = block * 8u + s;
    uint link = settledLinkOf(child);
    if (!linkLive(link)) {
      collapsible = false;
      continue;
    }
    NodeData data = nodeData(child);
    if (linkHasChildren(link) || !collapsibleData(first, data)) collapsible = false;
    if (data.log_odds > max_log_odds) max_log_odds = data.log_odds;
  }
  return NodeData(max_log_odds);
}

// updateOccupancyChildren alone (updateInnerOccupancy after an edit): see summariseChildren.
NodeData innerNodeData(uint block) {
  bool collapsible;
  return summariseChildren(block, collapsible);
}

// pruneNode: the data the node of a collapsible block takes (its first child's; all are equal).
NodeData prunedNodeData(uint block) { return nodeData(block * 8u); }

#endif  // OCTOVK_NODE_GLSL
