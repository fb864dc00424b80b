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

// What a node holds besides its link: its log-odds and its payload word (params.payload: none,
// ColorOcTree's colour or OcTreeStamped's time stamp; PAYLOAD is read and written only where the
// map has one, so a plain map's passes touch no more memory than before). Every copy,
// comparison and creation of a node's data goes through the functions below.
struct NodeData {
  float log_odds;
  uint payload;
};

bool hasPayload() { return params.payload != kPayloadNone; }

// OctoMap's getLogOdds / isNodeOccupied, for the passes that need no more of the data.
float nodeLogOdds(uint n) { return NODES[n].log_odds; }
bool nodeOccupied(uint n) { return nodeLogOdds(n) >= params.occupancy_log; }

// The payload word alone (0 for a map without one).
uint nodePayload(uint n) { return hasPayload() ? PAYLOAD[n] : 0u; }
void setNodePayload(uint n, uint payload) {
  if (hasPayload()) PAYLOAD[n] = payload;
}

NodeData nodeData(uint n) { return NodeData(NODES[n].log_odds, nodePayload(n)); }
// Node n as the pool holds it, link word and all, as one 64-bit word (the log-odds bits, the link
// word above them: a CaptureRecord's): for a copy of the pool (capture.comp), read after the
// passes that write it, one read where the Node struct takes two.
OCTOVK_ADDRESSED(NodeWordsRef, uint64_t, 8);
uint64_t storedNodeWord(uint n) { return NodeWordsRef(buffer_address[kBindNodes]).v[n]; }
void setNodeData(uint n, NodeData d) {
  NODES[n].log_odds = d.log_odds;
  setNodePayload(n, d.payload);
}

// The data of a node OctoMap creates (the root, createNodeChild): log-odds 0, white (no colour
// yet), stamp 0.
NodeData newNodeData() {
  return NodeData(0.0, params.payload == kPayloadColor ? kColorUnset : 0u);
}

// setLogOdds alone (clear_box's leaves take the lower clamping bound): a payload is kept.
void setNodeLogOdds(uint n, float log_odds) { NODES[n].log_odds = log_odds; }

// updateNodeLogOdds at a leaf of the scan: it takes `log_odds` (already clamped), the update's
// new value; OcTreeStamped's also stamps it (updateTimestamp, the scan's time).
void setUpdatedLeaf(uint n, float log_odds) {
  NODES[n].log_odds = log_odds;
  if (params.payload == kPayloadStamp) PAYLOAD[n] = params.stamp;
}

// isNodeCollapsible's test of a child's data against the first child's: the same log-odds;
// OcTreeStamped compares with OcTreeNodeStamped::operator==, so the stamps too; ColorOcTree's
// own isNodeCollapsible ignores colours.
bool collapsibleData(NodeData first, NodeData child) {
  return child.log_odds == first.log_odds &&
         (params.payload != kPayloadStamp || child.payload == first.payload);
}

// ColorOcTreeNode::isColorSet.
bool colorSet(uint c) { return (c & kColorUnset) != kColorUnset; }

// ColorOcTreeNode::getAverageChildColor over a block: the int mean of the set colours of the
// live children, white when none is set.
uint averageChildColor(uint block) {
  uvec3 sum = uvec3(0u);
  uint count = 0u;
  for (uint s = 0u; s < 8u; ++s) {
    uint child = block * 8u + s;
    if (!linkLive(settledLinkOf(child))) continue;
    uint c = PAYLOAD[child];
    if (!colorSet(c)) continue;
    sum += uvec3(c & 0xFFu, (c >> 8) & 0xFFu, (c >> 16) & 0xFFu);
    ++count;
  }
  if (count == 0u) return kColorUnset;
  uvec3 m = sum / count;
  return m.x | (m.y << 8) | (m.z << 16);
}

// The block of a node's children as updateNodeRecurs meets it going up, read plainly (the caller
// says why nothing writes it in the dispatch): whether pruneNode merges it (isNodeCollapsible:
// all 8 children exist, have no children and hold collapsible data), and the data node `n`
// takes when it keeps it (updateOccupancyChildren: the maximum log-odds of the live children,
// getMaxChildLogOdds from -FLT_MAX; OcTreeNodeStamped's also stamps the node with the scan's
// time; a colour stays as it was: OctoMap's updates leave inner colours alone). One pass over the
// block.
NodeData summariseChildren(uint n, uint block, out bool collapsible) {
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
    // A tile off the device (kFlagEvicted) has children there: never merged.
    if (linkHasChildren(link) || (link & kFlagEvicted) != 0u || !collapsibleData(first, data))
      collapsible = false;
    if (data.log_odds > max_log_odds) max_log_odds = data.log_odds;
  }
  uint payload = params.payload == kPayloadStamp ? params.stamp : nodePayload(n);
  return NodeData(max_log_odds, payload);
}

// updateInnerOccupancy at node `n` after an edit: its children's maximum log-odds; a colour
// becomes the children's average colour (ColorOcTree::updateInnerOccupancy), a stamp `stamp`
// where `at_time`, else the newest child's stamp (the edit has no clock of its own).
NodeData innerNodeData(uint n, uint block, bool at_time, uint stamp) {
  bool collapsible;
  NodeData d = summariseChildren(n, block, collapsible);
  if (params.payload == kPayloadColor) {
    d.payload = averageChildColor(block);
  } else if (params.payload == kPayloadStamp) {
    uint newest = 0u;
    for (uint s = 0u; s < 8u; ++s)
      if (linkLive(settledLinkOf(block * 8u + s))) newest = max(newest, PAYLOAD[block * 8u + s]);
    d.payload = at_time ? stamp : newest;
  }
  return d;
}

// pruneNode: the data the node of a collapsible block takes: its first child's (all have equal
// log-odds; OcTreeStamped's equal stamps too). ColorOcTree::pruneNode then, where child 0's
// colour is set, gives it the children's average colour.
NodeData prunedNodeData(uint block) {
  NodeData d = nodeData(block * 8u);
  if (params.payload == kPayloadColor && colorSet(d.payload)) d.payload = averageChildColor(block);
  return d;
}

#endif  // OCTOVK_NODE_GLSL
