// StoredMap and readStoredMap (include/octovk/store.hpp): an OccupancyMap loaded from a store's
// tiles, and scans committed through MapWriter, as `octovk integrate --store` commits them.
#include <algorithm>
#include <filesystem>
#include <map>
#include <utility>

#include "octovk/store.hpp"
#include "store/store.hpp"

namespace octovk {

namespace {

// The map's parameters as the store holds them, with the caller's device-memory cap.
MapParams storedParams(const store::MapInfo& info, std::size_t max_device_bytes) {
  MapParams params = info.params;
  params.max_device_bytes = max_device_bytes;
  return params;
}

}  // namespace

OccupancyMap readStoredMap(Context& context, const std::string& location, const std::string& name,
                           std::size_t max_device_bytes) {
  const std::unique_ptr<store::Store> store = store::Store::open(location, /*create=*/false);
  const store::MapInfo info = store::requireMap(*store, name);
  const HostTree tree = store::loadTree(*store, name);
  OccupancyMap map(context, storedParams(info, max_device_bytes));
  if (tree.root_exists) map.upload(tree);
  return map;
}

struct StoredMap::Impl {
  std::unique_ptr<store::Store> store;
  std::unique_ptr<store::MapWriter> writer;
  std::string name;
  std::optional<OccupancyMap> map;
  std::uint64_t last_seq = 0;
};

StoredMap::StoredMap(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
StoredMap::~StoredMap() = default;
StoredMap::StoredMap(StoredMap&&) noexcept = default;
StoredMap& StoredMap::operator=(StoredMap&&) noexcept = default;

StoredMap StoredMap::open(Context& context, const std::string& location, const std::string& name,
                          const std::optional<MapParams>& create) {
  const char* remedy = "give MapParams to create it (Python: resolution=)";
  std::error_code ec;
  if (!create && !store::isPostgresLocation(location) && !std::filesystem::exists(location, ec))
    throw Error(ErrorCode::kInvalidArgument, "store '" + location + "' does not exist; " + remedy);
  auto impl = std::make_unique<Impl>();
  impl->store = store::Store::open(location, /*create=*/create.has_value());
  impl->name = name;
  if (!create) (void)store::requireMap(*impl->store, name, remedy);
  impl->writer =
      std::make_unique<store::MapWriter>(*impl->store, name, create.value_or(MapParams{}));
  const std::size_t cap = create ? create->max_device_bytes : 0;
  impl->map.emplace(context, storedParams(impl->writer->info(), cap));
  const HostTree tree = impl->writer->load();
  if (tree.root_exists) impl->map->upload(tree);
  impl->last_seq = impl->store->map(name)->last_seq;
  return StoredMap(std::move(impl));
}

OccupancyMap& StoredMap::map() {
  if (!impl_) throw Error(ErrorCode::kInvalidArgument, "StoredMap: used after a move");
  return *impl_->map;
}
const std::string& StoredMap::name() const { return impl_->name; }
const std::string& StoredMap::location() const { return impl_->store->location(); }
std::uint64_t StoredMap::lastSeq() const { return impl_->last_seq; }

ScanStats StoredMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                      const Eigen::Vector3f& origin_world,
                                      const std::string& source, std::uint64_t scan,
                                      const ScanOptions& options) {
  return insert(
      [&](OccupancyMap& m) { return m.insertPointCloud(points_world, origin_world, options); },
      source, scan);
}

ScanStats StoredMap::insert(const std::function<ScanStats(OccupancyMap&)>& insert,
                            const std::string& source, std::uint64_t scan) {
  OccupancyMap& m = map();
  impl_->writer->begin(m);  // the write lock; other writers' scans loaded first
  ScanStats stats;
  try {
    stats = insert(m);
  } catch (...) {
    impl_->store->unlock();  // the map is as before the scan: nothing to commit
    throw;
  }
  try {
    impl_->last_seq = impl_->writer->commit(m, source, scan).seq;
  } catch (...) {
    impl_->writer->forget();  // the device map is ahead of the store: reload before the next
    throw;
  }
  return stats;
}

struct StoreFollower::Impl {
  std::unique_ptr<store::Store> store;
  std::string name;
  store::MapInfo info;
  std::map<std::uint64_t, store::Tile> tiles;  // the map's tiles as last read, by key
  HostTree tree;                               // the tree they make
  std::uint64_t seq = 0;
  bool polled = false;
};

namespace {

StoreFollower::TileBox boxOf(std::uint64_t key) {
  return {store::tileKeyCorner(key), store::tileKeyDepth(key)};
}

}  // namespace

StoreFollower::StoreFollower(const std::string& location, const std::string& name)
    : impl_(std::make_unique<Impl>()) {
  impl_->store = store::Store::open(location, /*create=*/false);
  impl_->name = name;
  impl_->info = store::requireMap(*impl_->store, name);
}
StoreFollower::~StoreFollower() = default;
StoreFollower::StoreFollower(StoreFollower&&) noexcept = default;
StoreFollower& StoreFollower::operator=(StoreFollower&&) noexcept = default;

std::optional<StoreFollower::Update> StoreFollower::poll() {
  Impl& f = *impl_;
  store::TileChanges changes = f.store->changesSince(f.name, f.seq);
  if (f.polled && changes.last_seq == f.seq) return std::nullopt;
  // The new state, checked whole before it replaces the old one.
  std::map<std::uint64_t, store::Tile> tiles;
  Update update;
  update.seq = changes.last_seq;
  // The upper stamps record (kUpperStampsKey) is read like a tile but is none: no box.
  for (const auto& [key, tile] : f.tiles)
    if (std::binary_search(changes.keys.begin(), changes.keys.end(), key))
      tiles.emplace(key, tile);
    else if (key != store::kUpperStampsKey)
      update.dropped.push_back(boxOf(key));
  for (store::Tile& t : changes.changed) {
    update.bytes_read += t.body.size();
    if (t.key != store::kUpperStampsKey) update.changed.push_back(boxOf(t.key));
    const std::uint64_t key = t.key;
    tiles[key] = std::move(t);
  }
  if (tiles.size() != changes.keys.size())
    throw Error(ErrorCode::kFormat, "store '" + f.store->location() + "', map '" + f.name +
                                        "': its tile list and its tiles disagree (" +
                                        std::to_string(changes.keys.size()) + " keys, " +
                                        std::to_string(tiles.size()) + " tiles)");
  std::vector<store::Tile> all;
  all.reserve(tiles.size());
  for (const auto& entry : tiles) all.push_back(entry.second);
  HostTree tree;
  try {
    tree = store::treeFromTiles(all, f.info.tile_depth, f.info.params.payload);  // all checked
  } catch (const Error& e) {
    throw Error(e.code(), "store '" + f.store->location() + "', map '" + f.name + "': " + e.what());
  }
  f.tiles = std::move(tiles);
  f.tree = std::move(tree);
  f.seq = changes.last_seq;
  f.polled = true;
  return update;
}

bool StoreFollower::wait(double seconds) {
  return impl_->store->waitForCommit(impl_->name, seconds);
}
const HostTree& StoreFollower::tree() const { return impl_->tree; }
const MapParams& StoreFollower::params() const { return impl_->info.params; }
unsigned StoreFollower::tileDepth() const { return impl_->info.tile_depth; }
std::uint64_t StoreFollower::seq() const { return impl_->seq; }

}  // namespace octovk
