// A store of maps as tiles (tiles.hpp): the interface every back end offers, and the writer that
// commits a map after each scan. One schema for every back end (docs/store.md):
//   maps  (name, resolution, sensor model, tile depth and format)
//   tiles (map, key, version, body): version = the log sequence number of the scan that wrote it
//   log   (map, seq, source, scan, time): one row per committed scan
// A scan's changed tiles and its log row commit in one transaction: a killed writer leaves the
// map as it was after its last committed scan.
#pragma once

#include <cstdint>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "map/pool_capture.hpp"
#include "octovk/octovk.hpp"
#include "store/tiles.hpp"

namespace octovk::store {

/// A map as the store describes it.
struct MapInfo {
  std::string name;
  /// The resolution and sensor model (prob_hit, prob_miss, clamping, occupancy threshold); the
  /// other fields keep their defaults.
  MapParams params;
  unsigned tile_depth = kTileDepth;
  std::uint64_t tiles = 0;       ///< tiles stored
  std::uint64_t tile_bytes = 0;  ///< their bodies' bytes
  std::uint64_t scans = 0;       ///< log rows
  std::uint64_t last_seq = 0;    ///< the last committed scan's sequence number (0: none)
};

/// One committed scan.
struct LogEntry {
  std::uint64_t seq = 0;     ///< 1, 2, ... per map, in commit order
  std::string source;        ///< the input as it was given (a scan graph, a folder)
  std::uint64_t scan = 0;    ///< the scan's 0-based index in `source`
  std::int64_t time_us = 0;  ///< commit time, microseconds since the Unix epoch (UTC)
};

/// What one scan's commit wrote.
struct CommitStats {
  std::uint64_t seq = 0;
  std::size_t tiles_written = 0;  ///< new or changed tiles
  std::size_t tiles_removed = 0;  ///< tiles that pruning merged into a larger one
  std::size_t body_bytes = 0;     ///< the written tiles' body bytes
  /// Tiles serialised and hashed to find them: the scan's (those on its updated paths, and new
  /// ones), or every tile when the map changed otherwise since the last commit.
  std::size_t tiles_compared = 0;
  double find_s = 0.0;   ///< seconds finding them: capture, cut, serialise, hash
  double write_s = 0.0;  ///< seconds of the store's transaction
};

/// What a map's tiles are at one commit, against an earlier one (Store::changesSince).
struct TileChanges {
  std::uint64_t last_seq = 0;       ///< the sequence number the snapshot is at
  std::vector<std::uint64_t> keys;  ///< every tile the map holds, sorted
  std::vector<Tile> changed;        ///< the tiles written after the earlier commit, sorted
};

/// A store's back end. Every call is one transaction; errors are Error(kIo) naming the store
/// and what failed (kInvalidArgument for a request the store refuses).
class Store {
 public:
  virtual ~Store() = default;
  /// The store at `location`: a PostgreSQL connection URI (postgresql://...), or an SQLite file
  /// (created when `create` and missing).
  static std::unique_ptr<Store> open(const std::string& location, bool create);

  /// How messages name the store ("map.sqlite").
  virtual const std::string& location() const = 0;
  virtual std::vector<MapInfo> maps() = 0;
  virtual std::optional<MapInfo> map(const std::string& name) = 0;
  /// Creates map `name` unless it exists (another writer may have created it meanwhile): true
  /// when this call created it.
  virtual bool createMap(const std::string& name, const MapParams& params) = 0;
  /// Every tile of the map and the sequence number they are current at, read in one snapshot
  /// (inside lock()'s transaction when one is open).
  virtual std::vector<Tile> tiles(const std::string& name, std::uint64_t* last_seq) = 0;
  /// What changed in map `name` after scan `since` (a sequence number; 0: every tile), in one
  /// snapshot: the keys of all its tiles (a follower drops the ones no longer there: pruning
  /// merged them) and the bodies of those written after `since` only.
  virtual TileChanges changesSince(const std::string& name, std::uint64_t since) = 0;
  virtual std::vector<LogEntry> log(const std::string& name) = 0;
  /// Waits up to `seconds` for a scan committed to map `name`: true as soon as one is (a
  /// back end that can be told: PostgreSQL's LISTEN/NOTIFY), false when the time is up (the
  /// default: it only sleeps; a follower then reads the store to find out).
  virtual bool waitForCommit(const std::string& name, double seconds);
  /// Opens a scan's transaction: takes the map's write lock (other writers wait for it until
  /// this one commits) and returns the map's last sequence number.
  virtual std::uint64_t lock(const std::string& name) = 0;
  /// Abandons lock()'s transaction (nothing of it is written); nothing when none is open.
  virtual void unlock() = 0;
  /// One scan, all or nothing: writes `changed` (version entry.seq), removes `removed` and adds
  /// the log row `entry`, in lock()'s transaction when one is open (else in its own). Refused
  /// (kInvalidArgument, nothing written) unless the map's last sequence number is
  /// entry.seq - 1: another writer committed in between.
  virtual void commit(const std::string& name, std::span<const Tile> changed,
                      std::span<const std::uint64_t> removed, const LogEntry& entry) = 0;
};

/// info.params.payload from the map's stored tile format (tileFormatOf); kInvalidArgument naming
/// `what` (the map and its store) for a format or a tile depth (info.tile_depth) this octovk does
/// not read.
void readTileFormat(MapInfo& info, std::int64_t format, const std::string& what);

/// Whether `location` names a PostgreSQL store (postgresql://... or postgres://...).
bool isPostgresLocation(const std::string& location);
/// The PostgreSQL store at `location`, a libpq connection URI (its schema created when missing).
std::unique_ptr<Store> openPostgresStore(const std::string& location);

/// A map in a store, written after each scan: keeps a hash of each committed tile to find the
/// tiles a scan changed.
class MapWriter {
 public:
  /// Opens map `name`, creating it with `params` when it is missing.
  MapWriter(Store& store, std::string name, const MapParams& params);
  /// Waits for a commit running in the background (its error is dropped: the store holds the
  /// scans before it).
  ~MapWriter();
  MapWriter(const MapWriter&) = delete;
  MapWriter& operator=(const MapWriter&) = delete;
  /// Whether the map existed (and so holds its own parameters: info().params).
  bool existed() const { return existed_; }
  const MapInfo& info() const { return info_; }
  /// The committed map (empty when new), for OccupancyMap::upload.
  HostTree load();
  /// Before a scan is committed: waits for a background commit (finish(), its error thrown),
  /// takes the map's write lock, and when other writers committed scans since this one's last,
  /// loads the map as they left it into `map` (after the scans submitted to it, which the load
  /// replaces). The scan then applies to the map the log's order says, and commit() releases
  /// the lock. True when the map was reloaded: a scan submitted before the call is gone and must
  /// be inserted again. Called before the scan is submitted, or after it (to let the scan run
  /// on the device while the last commit's transaction ends).
  bool begin(OccupancyMap& map);
  /// Commits `map` as it is after scan `scan` of `source`: its tiles that differ from the last
  /// committed ones, and the log row. Waits for the map's submitted scans first.
  CommitStats commit(OccupancyMap& map, const std::string& source, std::uint64_t scan);
  /// commit(), while the caller goes on with the next scan. The map's scans from this call on
  /// copy the pool to host staging in their own submission (StoreAccess::captureScans); when
  /// this scan did, its commit waits for the next finish() (or begin(), commit()), which waits
  /// for this scan only, then finds the tiles and runs the transaction while the scans
  /// submitted after it run on the device. Otherwise (the first scan, an empty one, a map that
  /// spills tiles) the map is captured now, after its scans, and the tiles and the transaction
  /// run on a thread of their own until then. Until finish() nothing else may use the store.
  void commitInBackground(OccupancyMap& map, const std::string& source, std::uint64_t scan);
  /// Waits for a background commit and returns its statistics (all zero: none). Its error is
  /// thrown naming the scan (kIo from the store), and the writer forgets the map (the next
  /// begin() reloads it).
  CommitStats finish();
  /// After an error elsewhere: waits for a background commit, drops its error and what it
  /// captured (a device buffer: gone before the map is), and forgets the map.
  void abandon() noexcept;
  /// The sums of the commits so far (seq: how many), and the most body bytes one wrote.
  const CommitStats& totals() const { return totals_; }
  /// How often begin() loaded other writers' scans, and the seconds it took in all.
  std::size_t reloads() const { return reloads_; }
  double reloadSeconds() const { return reload_s_; }
  std::size_t maxBodyBytes() const { return max_body_bytes_; }
  /// Forgets what was committed: the next begin() loads the map from the store (after a failed
  /// commit, when the device map holds a scan the store does not).
  void forget() {
    hashes_.clear();
    bodies_.clear();
    bodies_known_ = false;
    last_seq_ = ~std::uint64_t{0};
    version_ = kUnknownVersion;
  }

 private:
  Store& store_;
  std::string name_;
  MapInfo info_;
  bool existed_ = false;
  static constexpr std::uint64_t kUnknownVersion = ~std::uint64_t{0};
  /// A scan's commit: the map captured, then its tiles found, then the store's transaction.
  struct PendingCommit {
    std::string source;
    std::uint64_t scan = 0;
    PoolCapture pool;
    std::vector<Tile> changed;
    std::vector<std::uint64_t> removed;
    LogEntry entry;
    /// The new hashes of the tiles in `changed` (and the upper stamps record), by key.
    std::vector<std::pair<std::uint64_t, std::uint64_t>> updated;
    /// Tiles off the device with changes no commit has seen (StoreAccess::takeDirtyTiles), by
    /// tile key: their subtrees.
    std::unordered_map<std::uint64_t, HostTree> dirty;
    CommitStats stats;
  };
  /// The map captured after its scans (on the caller's thread: the device).
  std::unique_ptr<PendingCommit> capture(OccupancyMap& map, const std::string& source,
                                         std::uint64_t scan);
  /// The changed tiles of a capture, against the last commit (host work only).
  void prepare(PendingCommit& c) const;
  /// The store's transaction.
  void write(PendingCommit& c);
  /// The writer's state once `c` is committed.
  void apply(PendingCommit& c);

  std::uint64_t last_seq_ = 0;
  /// Key -> hash of the body, in key order: a scan's changed regions are key ranges.
  std::map<std::uint64_t, std::uint64_t> hashes_;
  /// The device map's tree version (StoreAccess::version) that `hashes_` describe; unknown:
  /// the next commit compares every tile.
  std::uint64_t version_ = kUnknownVersion;
  std::unique_ptr<PendingCommit> pending_commit_;  // what background_ commits
  /// A commit whose capture comes with its scan's submission (StoreAccess::capturingTicket):
  /// finish() takes it once the scan is done, while the next scan runs.
  struct Deferred {
    OccupancyMap* map = nullptr;
    std::string source;
    std::uint64_t scan = 0;
    std::uint64_t ticket = 0;
  };
  std::optional<Deferred> deferred_;
  /// The commit of `pending`, failed with `e`: the writer forgets the map, and the error names
  /// the scan.
  [[noreturn]] void failed(const Error& e, const PendingCommit& pending);
  /// Runs `work` (the rest of the commit of `pending`): its Error goes through failed(), any
  /// other exception after forget().
  template <class Work>
  void commitOrForget(const PendingCommit& pending, Work&& work);
  /// Checks that `map` is of the stored map's type.
  void requireType(const OccupancyMap& map) const;
  std::future<void> background_;
  CommitStats totals_;
  std::size_t max_body_bytes_ = 0;
  /// Every tile's body as committed, kept once another writer's scans were first loaded: later
  /// loads read only the tiles written since (Store::changesSince) instead of the whole map.
  std::unordered_map<std::uint64_t, std::string> bodies_;
  bool bodies_known_ = false;
  std::size_t reloads_ = 0;
  double reload_s_ = 0.0;
  /// Every tile of the map, read in one snapshot (sets last_seq_): the hashes replaced, and the
  /// bodies when `keep_bodies`.
  std::vector<Tile> readAll(bool keep_bodies);
  /// The map as the store holds it after other writers' scans (begin()).
  HostTree reload();
};

/// The hash MapWriter keeps of a body.
std::uint64_t bodyHash(const std::string& body);

/// Map `name` of `store`, or kInvalidArgument naming the store, the map and where its maps are
/// listed (`remedy`, when given, comes first: "give MapParams to create it").
MapInfo requireMap(Store& store, const std::string& name, const std::string& remedy = "");

/// The map's tree as the store holds it.
HostTree loadTree(Store& store, const std::string& name);

}  // namespace octovk::store
