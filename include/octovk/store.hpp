// A map kept in a store (an SQLite file or a PostgreSQL database; docs/store.md) as well as on
// the device, as `octovk integrate --store` keeps it: opened as its last committed scan left it,
// and each scan inserted through it committed (its changed tiles and a log row, one
// transaction). Link octovk::store (find_package(octovk COMPONENTS store); pkg-config
// octovk-store), which brings SQLite and libpq.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "octovk/octovk.hpp"

namespace octovk {

/// The map `name` of the store at `location` (a PostgreSQL URI postgresql://..., or an SQLite
/// file) as its last committed scan left it, on `context`: a snapshot, which later scans into the
/// store do not change. kInvalidArgument when the store holds no such map, kIo when the store
/// cannot be read, kFormat for a damaged tile, kOutOfDeviceMemory over `max_device_bytes`.
OccupancyMap readStoredMap(Context& context, const std::string& location,
                           const std::string& name = "default", std::size_t max_device_bytes = 0);

/// A map of a store that scans are inserted into, each one committed.
///
/// Several writers (processes, machines) may insert into one map at once: each scan takes the
/// map's write lock, first loads what other writers committed since this one's last scan, then
/// inserts and commits, so the map equals OctoMap inserting the log's scans in its order. A
/// plain, colour or stamped map (MapParams::payload; scans then carry ScanOptions::colors or
/// ScanOptions::stamp as a ColorMap's or StampedMap's do). One thread at a time, as an
/// OccupancyMap.
class StoredMap {
 public:
  /// Opens map `name` of the store at `location` on `context`. A map that is missing (and an
  /// SQLite file that is missing) is created with `create`'s resolution, sensor model and
  /// payload when given, else kInvalidArgument; an existing map keeps its own parameters and
  /// payload (`create` ignored but for max_device_bytes, which caps the device map).
  static StoredMap open(Context& context, const std::string& location,
                        const std::string& name = "default",
                        const std::optional<MapParams>& create = std::nullopt);
  ~StoredMap();
  StoredMap(StoredMap&&) noexcept;
  StoredMap& operator=(StoredMap&&) noexcept;

  /// The device map, as of the last scan committed through this object (or loaded since):
  /// queries, exports and every other read. Change it only through insertPointCloud: a change
  /// made to it directly (a scan, an edit) would be committed with the next scan, under that
  /// scan's log row, and the log would no longer replay to the map.
  OccupancyMap& map();
  /// The map's name, the store as messages name it, and the last sequence number this object
  /// committed or loaded (0: none).
  const std::string& name() const;
  const std::string& location() const;
  std::uint64_t lastSeq() const;

  /// OccupancyMap::insertPointCloud, committed: the log row names `source` and `scan` (what
  /// `octovk store log` prints; a replay of the log finds the scan by them). When the commit
  /// fails (kIo) the device map holds the scan but the store does not: the next scan reloads
  /// the map from the store first.
  ScanStats insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                             const Eigen::Vector3f& origin_world, const std::string& source,
                             std::uint64_t scan, const ScanOptions& options = {});
  /// Any one blocking scan, committed: `insert` runs on the map between the lock (other
  /// writers' scans loaded) and the commit, and must make exactly one blocking insert call
  /// (insertPointCloud with a pose, insertDepthImage, ...); what it returns is returned.
  ScanStats insert(const std::function<ScanStats(OccupancyMap&)>& insert, const std::string& source,
                   std::uint64_t scan);

 private:
  struct Impl;
  explicit StoredMap(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Follows a map of a store while writers commit scans to it: each poll() reads what was
/// committed since the last one, in one snapshot of the store: the keys of the map's tiles and the
/// bodies of only the tiles written since (a tile: the subtree at depth `tileDepth()` of OctoMap's
/// 16, 16^3 finest cells). No device is needed; tree() gives the map to upload or write.
class StoreFollower {
 public:
  /// A tile as its finest cells' OctoMap keys span it: [min_key, min_key + 2^(16 - depth)).
  struct TileBox {
    Key min_key{};
    unsigned depth = 0;  ///< the tile's depth: tileDepth(), or less for a pruned larger leaf
  };
  /// What one poll found: the sequence number it reached, the tiles written since the last poll
  /// (new or changed), and the tiles that are gone (merged by pruning into a larger leaf).
  struct Update {
    std::uint64_t seq = 0;
    std::vector<TileBox> changed;
    std::vector<TileBox> dropped;
    std::size_t bytes_read = 0;  ///< the changed tiles' bodies
  };

  /// Opens map `name` of the store at `location` (kInvalidArgument when it holds no such map,
  /// kIo when it cannot be read). Nothing is read until the first poll().
  StoreFollower(const std::string& location, const std::string& name = "default");
  ~StoreFollower();
  StoreFollower(StoreFollower&&) noexcept;
  StoreFollower& operator=(StoreFollower&&) noexcept;

  /// Reads what was committed since the last poll: nothing (std::nullopt) when no scan was; the
  /// first poll reads every tile. kFormat for a damaged tile (the follower is then as before).
  std::optional<Update> poll();
  /// Waits up to `seconds` for the next commit to the map: true as soon as one is made (a
  /// PostgreSQL store tells its followers: LISTEN/NOTIFY), false when the time is up (an SQLite
  /// store only sleeps). poll() then reads it.
  bool wait(double seconds);
  /// The map as of the last poll (empty before the first), as OccupancyMap::upload takes it.
  const HostTree& tree() const;
  /// The map's resolution and sensor model, as the store holds them.
  const MapParams& params() const;
  unsigned tileDepth() const;
  /// The sequence number of the last poll (0: none yet, or no scan committed).
  std::uint64_t seq() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A TileSpill (OccupancyMap::spillTilesTo) in a private temporary SQLite file: SQLite makes it
/// in its temporary directory (SQLITE_TMPDIR, else TMPDIR, else /var/tmp or /tmp) and removes it
/// when the spill is destroyed or the process ends, however it ends. What `octovk integrate` uses
/// for a map that outgrows --max-device-memory without --store. kIo where it cannot be made.
std::shared_ptr<TileSpill> sqliteTileSpill();

}  // namespace octovk
