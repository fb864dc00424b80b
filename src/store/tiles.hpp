// The map cut into tiles, the unit a store keeps: the subtrees that hang at one fixed depth, each
// serialised as OctoMap's .ot node stream. The tree above the tile depth is not stored: it is
// derived from the tiles (inner values, OctoMap's pruning across tiles), so that a tree rebuilt
// from its tiles is the tree that was cut, node for node.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "gpu/gpu_types.h"
#include "octovk/octovk.hpp"

namespace octomap {
class OcTree;
}

namespace octovk {
struct PoolCapture;
}

namespace octovk::store {

/// The depth (of OctoMap's 16) at which the map is cut: a tile is 16^3 finest cells (0.8 m at
/// 0.05 m). Measured on FR-079's first 500 scans (docs/store.md, 'Tile depth'): a scan rewrites
/// 85 KB at depth 12 against 214 KB at 10 and 390 KB at 8 (0.05 m), in 65 tiles; depth 13 halves
/// the bytes again with 2.3x the tiles, too small a unit for a device's working set.
inline constexpr unsigned kTileDepth = gpu::kTileDepth;
/// The tile key and body formats below, by the map's payload: a store records the map's format
/// and refuses others. 1: OcTree (a record is the log-odds and the child byte, 5 bytes), 2:
/// ColorOcTree (the log-odds, r, g, b and the child byte: ColorOcTreeNode::writeData's record,
/// 8 bytes), 3: OcTreeStamped (the log-odds, the stamp as 4 little-endian bytes and the child
/// byte, 9 bytes: octovk's own, since OctoMap writes no stamps).
unsigned tileFormatOf(Payload payload);
/// The payload of tile format `format`; nullopt for one this octovk does not read.
std::optional<Payload> payloadOfTileFormat(std::int64_t format);
/// The bytes of one node record in a tile body of a map with `payload`.
std::size_t recordBytes(Payload payload);
/// Not a tile: a stamped map's stamps of the nodes above the tile depth that have children (its
/// inner nodes there, whose stamps the tiles do not derive: OctoMap gives an inner node the time
/// of the last update under it, and a degrade's time). Its body: per such node, in key order, its
/// tileKey (8 bytes) and its stamp (4 bytes), little-endian. Depth field 31: no tile has it.
inline constexpr std::uint64_t kUpperStampsKey = 31;

/// A tile: the node at the tile depth with its subtree, or a leaf above that depth (a pruned
/// region that covers several tiles, as OctoMap's tree holds it).
struct Tile {
  /// tileKey(depth, path): where the tile's root hangs.
  std::uint64_t key = 0;
  /// The subtree's node records as OctoMap's .ot data section holds them (OcTree::writeData):
  /// per node its float log-odds (and payload: recordBytes), then a byte with a bit per existing
  /// child, children following depth first. A plain or colour map's body is itself OctoMap's
  /// readData input for the subtree; a colour tile's inner nodes hold the colours
  /// ColorOcTree::updateInnerOccupancy gives them.
  std::string body;
  friend bool operator==(const Tile&, const Tile&) = default;
};

/// The key of the node at `depth` (0..16) reached by `path`: its child indices from the root,
/// 3 bits each, the first in the highest bits. The path is aligned to 16 levels (the Morton
/// order of OctoMap's keys' top bits), then the depth takes the 5 low bits: sorting keys sorts
/// tiles depth first, in the order of OctoMap's node stream. Fits an SQL 64-bit integer.
std::uint64_t tileKey(unsigned depth, std::uint64_t path);
/// The depth of a tile key.
unsigned tileKeyDepth(std::uint64_t key);
/// The OctoMap key (k[0], k[1], k[2]) of the first finest cell of a tile: the tile's corner.
Key tileKeyCorner(std::uint64_t key);
/// The path (tileKey's) from the root to the finest cell `key`, all 16 levels: the tile at
/// depth d holding it is tileKey(d, cellPath(key) >> 3 * (16 - d)).
std::uint64_t cellPath(const Key& key);

/// The tiles of `tree` cut at `tile_depth` (1..16), sorted by key, in the format of its payload
/// (with the upper stamps record, kUpperStampsKey, first for a stamped tree). kFormat for a
/// tree whose links leave it.
std::vector<Tile> tilesOf(const HostTree& tree, unsigned tile_depth = kTileDepth);

/// A tile of a captured device pool (PoolCapture): its key, and its root node in the pool at
/// its depth; its body is read only when asked for (poolTileBody).
struct PoolTile {
  std::uint64_t key = 0;
  std::uint32_t node = 0;
  unsigned depth = 0;
};
/// The tiles of the tree in `pool` cut at `tile_depth` (1..16), in key order, without their
/// bodies: a walk of the tree above the tile depth. kFormat for links that leave the pool.
std::vector<PoolTile> poolTiles(const PoolCapture& pool, unsigned tile_depth = kTileDepth);
/// What a scan may have changed among the tiles of a captured pool whose `changed` list is
/// complete (PoolCapture::incremental): found by walking only into the changed nodes above the
/// tile depth, so that the cost follows the scan and not the map.
struct PoolTileChanges {
  /// The tiles that hang from changed nodes and are changed themselves, in key order: to be
  /// compared with the committed ones. Every other tile of the tree is as committed.
  std::vector<PoolTile> tiles;
  /// Key ranges [first, second) in which a committed tile is gone unless it is in `tiles`: the
  /// ranges of those tiles (a subtree pruned into a leaf above the tile depth), the child slots
  /// without a child of the walked nodes, and the walked nodes' own keys (a leaf that grew
  /// children). They may overlap.
  std::vector<std::pair<std::uint64_t, std::uint64_t>> cleared;
};
/// The changed tiles of `pool` cut at `tile_depth` (1..16), against the commit that
/// pool.changed is relative to, whose tile keys `committed` knows (a leaf it holds that now has
/// children was expanded: all under it is new); everything cleared when the pool has no root.
/// Meaningful only where pool.incremental holds.
PoolTileChanges changedPoolTiles(const PoolCapture& pool, unsigned tile_depth,
                                 const std::function<bool(std::uint64_t)>& committed);
/// The keys of the tiles under the node at `depth` reached by `path` (itself included):
/// [first, second), every depth below it.
std::pair<std::uint64_t, std::uint64_t> tileKeyRange(unsigned depth, std::uint64_t path);
/// The body of a tile of `pool` (Tile::body): what tilesOf gives for the same tree.
std::string poolTileBody(const PoolCapture& pool, const PoolTile& tile);
/// The body of the upper stamps record (kUpperStampsKey) of a stamped `pool`; empty when the
/// tree has no node with children above the tile depth.
std::string poolUpperStamps(const PoolCapture& pool, unsigned tile_depth = kTileDepth);

/// The tree (of `payload`) that `tiles` (any order) cut at `tile_depth` came from: each tile's
/// subtree as its body holds it, and above the tile depth what OctoMap's tree holds there: an
/// inner node's log-odds is the largest of its children's, and a node whose 8 children are
/// leaves of equal log-odds (and stamps, OcTreeNodeStamped::operator==) is itself a leaf of that
/// log-odds (pruneNode). Colours there are ColorOcTree's (a pruned node's as its pruneNode
/// gives it, an inner node's the mean of its children's); stamps those of the upper stamps
/// record (the largest child stamp for a node it lacks). kFormat naming the tile when a key or a
/// body is damaged (a record past the end or after the last, a non-finite log-odds, a node below
/// depth 16 or a tile under another).
HostTree treeFromTiles(std::span<const Tile> tiles, unsigned tile_depth = kTileDepth,
                       Payload payload = Payload::kNone);

/// The .ot data section of `tree` in its tile format (OcTree::writeData's bytes for a plain
/// tree); empty for an empty tree.
std::string nodeStream(const HostTree& tree);

/// `tree` as an OctoMap tree with `params`' resolution and sensor model (what .bt's
/// max-likelihood conversion reads), through OctoMap's own reader of the node stream.
std::unique_ptr<octomap::OcTree> ocTreeOf(const HostTree& tree, const MapParams& params);

}  // namespace octovk::store
