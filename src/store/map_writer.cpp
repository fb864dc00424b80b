// MapWriter: the map committed to a store after each scan, only the tiles that changed.
#include <algorithm>
#include <chrono>
#include <string_view>
#include <thread>
#include <utility>

#include "map/store_access.hpp"
#include "store/store.hpp"

namespace octovk::store {

std::uint64_t bodyHash(const std::string& body) {
  // 64 bits, with the size mixed in: a changed tile mistaken for its old self would be lost.
  const std::uint64_t h = std::hash<std::string_view>{}(body);
  return h ^ (body.size() * 0x9E3779B97F4A7C15ull);
}

bool Store::waitForCommit(const std::string&, double seconds) {
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  return false;
}

MapInfo requireMap(Store& store, const std::string& name, const std::string& remedy) {
  std::optional<MapInfo> info = store.map(name);
  if (!info)
    throw Error(ErrorCode::kInvalidArgument,
                "store '" + store.location() + "' holds no map '" + name + "'; " +
                    (remedy.empty() ? std::string() : remedy + ", or ") + "'octovk store info " +
                    store.location() + "' lists its maps");
  return *info;
}

HostTree loadTree(Store& store, const std::string& name) {
  const MapInfo info = requireMap(store, name);
  const std::vector<Tile> tiles = store.tiles(name, nullptr);
  try {
    return treeFromTiles(tiles, info.tile_depth);
  } catch (const Error& e) {
    throw Error(e.code(), "store '" + store.location() + "', map '" + name + "': " + e.what());
  }
}

MapWriter::MapWriter(Store& store, std::string name, const MapParams& params)
    : store_(store), name_(std::move(name)) {
  existed_ = !store_.createMap(name_, params);
  info_ = *store_.map(name_);
}

HostTree MapWriter::load() {
  const std::vector<Tile> tiles = store_.tiles(name_, &last_seq_);
  hashes_.clear();
  for (const Tile& t : tiles) hashes_[t.key] = bodyHash(t.body);
  try {
    return treeFromTiles(tiles, info_.tile_depth);
  } catch (const Error& e) {
    throw Error(e.code(), "store '" + store_.location() + "', map '" + name_ + "': " + e.what());
  }
}

bool MapWriter::begin(OccupancyMap& map) {
  map.flush();
  const std::uint64_t last = store_.lock(name_);
  if (last == last_seq_) return false;
  try {
    const HostTree tree = load();  // in the locked transaction: sets last_seq_
    map.upload(tree);
    version_ = StoreAccess::version(map);  // the tree the hashes describe
  } catch (...) {
    store_.unlock();
    forget();  // the map is unknown: the next begin() loads it again
    throw;
  }
  return true;
}

CommitStats MapWriter::commit(OccupancyMap& map, const std::string& source, std::uint64_t scan) {
  map.flush();
  using Clock = std::chrono::steady_clock;
  const auto seconds = [](Clock::time_point from) {
    return std::chrono::duration<double>(Clock::now() - from).count();
  };
  const auto start = Clock::now();
  if (map.params().payload != Payload::kNone)
    throw Error(ErrorCode::kInvalidArgument,
                std::string("a store holds plain occupancy maps (OcTree), not ") +
                    treeTypeName(map.params().payload) + " maps");
  // The pool as the device holds it, and the nodes above the tile depth that the scan changed
  // (when the map is the last commit's plus this one scan): only their tiles, and tiles new
  // since, are serialised and compared; the others are as committed.
  const PoolCapture pool = StoreAccess::capture(map, version_, info_.tile_depth);
  const bool incremental = pool.incremental && version_ != kUnknownVersion;
  const std::vector<PoolTile> tiles = poolTiles(pool, info_.tile_depth);
  CommitStats stats;
  std::vector<Tile> changed;
  std::unordered_map<std::uint64_t, std::uint64_t> hashes;
  hashes.reserve(tiles.size());
  for (const PoolTile& t : tiles) {
    const auto old = hashes_.find(t.key);
    if (incremental && old != hashes_.end() &&
        !std::binary_search(pool.changed.begin(), pool.changed.end(), t.node)) {
      hashes.emplace(t.key, old->second);
      continue;
    }
    std::string body = poolTileBody(pool, t);
    const std::uint64_t h = bodyHash(body);
    hashes.emplace(t.key, h);
    ++stats.tiles_compared;
    if (old == hashes_.end() || old->second != h) {
      stats.body_bytes += body.size();
      changed.push_back({t.key, std::move(body)});
    }
  }
  std::vector<std::uint64_t> removed;
  for (const auto& [key, h] : hashes_)
    if (!hashes.contains(key)) removed.push_back(key);
  LogEntry entry;
  entry.seq = last_seq_ + 1;
  entry.source = source;
  entry.scan = scan;
  entry.time_us = std::chrono::duration_cast<std::chrono::microseconds>(
                      std::chrono::system_clock::now().time_since_epoch())
                      .count();
  stats.find_s = seconds(start);
  const auto write_start = Clock::now();
  store_.commit(name_, changed, removed, entry);
  stats.write_s = seconds(write_start);
  // Only once committed: a failed commit leaves the writer as before, to be tried again.
  hashes_ = std::move(hashes);
  last_seq_ = entry.seq;
  version_ = pool.version;
  stats.seq = entry.seq;
  stats.tiles_written = changed.size();
  stats.tiles_removed = removed.size();
  return stats;
}

}  // namespace octovk::store
