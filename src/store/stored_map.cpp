// StoredMap and readStoredMap (include/octovk/store.hpp): an OccupancyMap loaded from a store's
// tiles, and scans committed through MapWriter, as `octovk integrate --store` commits them.
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
  const std::optional<store::MapInfo> info = store->map(name);
  if (!info)
    throw Error(ErrorCode::kInvalidArgument, "store '" + store->location() + "' holds no map '" +
                                                 name + "'; 'octovk store info " +
                                                 store->location() + "' lists its maps");
  const HostTree tree = store::loadTree(*store, name);
  OccupancyMap map(context, storedParams(*info, max_device_bytes));
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
  if (create && create->payload != Payload::kNone)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("StoredMap: a store keeps plain occupancy maps only, not ") +
                    treeTypeName(create->payload) + " maps (MapParams::payload)");
  auto impl = std::make_unique<Impl>();
  impl->store = store::Store::open(location, /*create=*/create.has_value());
  impl->name = name;
  if (!create && !impl->store->map(name))
    throw Error(ErrorCode::kInvalidArgument,
                "store '" + impl->store->location() + "' holds no map '" + name +
                    "'; give MapParams to create it, or 'octovk store info " +
                    impl->store->location() + "' lists its maps");
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
  OccupancyMap& m = map();
  impl_->writer->begin(m);  // the write lock; other writers' scans loaded first
  ScanStats stats;
  try {
    stats = m.insertPointCloud(points_world, origin_world, options);
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

}  // namespace octovk
