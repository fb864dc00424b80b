// The program's side of the map store (store.cpp): `octovk store export|follow|log|info`, and what
// `octovk integrate --store STORE [--map NAME]` adds to integrate, in a few calls from there.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "cli.hpp"
#include "report.hpp"

namespace octovk::store {
class Store;
class MapWriter;
}  // namespace octovk::store

namespace octovk::cli {

/// `octovk store ACTION ...`: runs the action on the words after it (help included).
int runStoreActions(const std::vector<std::string>& args);
void printStoreHelp(std::ostream& out);

/// integrate's --store and --map: the map is read from the store first (or created there), and
/// each scan is committed to it, its changed tiles and its log row in one transaction.
class IntegrateStore {
 public:
  IntegrateStore();
  ~IntegrateStore();
  /// The options integrate hands over first: true for --store / --map; the sensor-model options
  /// are noted (a map that exists refuses other values) and left to integrate (false).
  bool option(const ParsedOption& option);
  /// Whether --store was given: then -o is optional.
  bool enabled() const { return !path_.empty(); }
  /// Opens the store and the map before the map is made: a new map takes `params`; an existing
  /// one gives its resolution and sensor model to `params`, and refuses different ones given.
  void open(MapParams& params);
  /// Uploads the committed map into `map` (nothing for a new one).
  void load(OccupancyMap& map);
  /// After each scan is submitted (it runs on the device meanwhile): waits for the last scan's
  /// commit, takes the map's write lock, and loads the scans other writers committed since
  /// (the map is reloaded from the store, the submitted scan dropped), so that the map is the
  /// log's. True when reloaded: submit the scan again.
  bool begin(OccupancyMap& map);
  /// Commits `map` after scan `scan` of `source`: waits for the scan, finds its tiles and
  /// leaves the store's transaction running while the next scan is submitted.
  void commit(OccupancyMap& map, const std::string& source, std::size_t scan);
  /// Waits for the last commit (its error thrown).
  void finish();
  /// After an error: waits for the last commit, dropping it and its error (MapWriter::abandon).
  void abandon() noexcept;
  /// The store's lines of integrate's summary.
  void report(Report& report) const;
  /// integrate's help lines for --store and --map.
  static void printHelp(std::ostream& out);

 private:
  std::string path_;
  std::string map_name_ = "default";
  std::vector<std::string> sensor_options_;  // given: --resolution, --prob-hit, ...
  std::unique_ptr<store::Store> store_;
  std::unique_ptr<store::MapWriter> writer_;
  bool existed_ = false;
};

}  // namespace octovk::cli
