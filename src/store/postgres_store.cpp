// The PostgreSQL back end (libpq): the SQLite schema in PostgreSQL's types, for a map shared by
// machines. A scan's commit locks its map's row (SELECT ... FOR UPDATE), so writers of one map
// take turns; a reader's snapshot is one REPEATABLE READ transaction.
#include <libpq-fe.h>
#include <poll.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <string_view>
#include <utility>

#include "store/store.hpp"

namespace octovk::store {

namespace {

constexpr int kSchemaVersion = 1;
constexpr const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS octovk_schema (version INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS maps (
  id BIGSERIAL PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  resolution DOUBLE PRECISION NOT NULL,
  prob_hit DOUBLE PRECISION NOT NULL,
  prob_miss DOUBLE PRECISION NOT NULL,
  clamping_min DOUBLE PRECISION NOT NULL,
  clamping_max DOUBLE PRECISION NOT NULL,
  occupancy_threshold DOUBLE PRECISION NOT NULL,
  tile_depth INTEGER NOT NULL,
  tile_format INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS tiles (
  map BIGINT NOT NULL REFERENCES maps(id),
  key BIGINT NOT NULL,
  version BIGINT NOT NULL,
  body BYTEA NOT NULL,
  PRIMARY KEY (map, key));
CREATE TABLE IF NOT EXISTS log (
  map BIGINT NOT NULL REFERENCES maps(id),
  seq BIGINT NOT NULL,
  source TEXT NOT NULL,
  scan BIGINT NOT NULL,
  time_us BIGINT NOT NULL,
  PRIMARY KEY (map, seq));
)sql";

// The URI without its password, for messages.
std::string withoutPassword(const std::string& uri) {
  const std::size_t scheme = uri.find("://");
  const std::size_t at = uri.find('@');
  if (scheme == std::string::npos || at == std::string::npos) return uri;
  const std::size_t colon = uri.find(':', scheme + 3);
  if (colon == std::string::npos || colon > at) return uri;
  return uri.substr(0, colon + 1) + "***" + uri.substr(at);
}

class Result {
 public:
  explicit Result(PGresult* r) : r_(r) {}
  ~Result() { PQclear(r_); }
  Result(const Result&) = delete;
  Result& operator=(const Result&) = delete;
  int rows() const { return PQntuples(r_); }
  std::string text(int row, int col) const {
    return std::string(PQgetvalue(r_, row, col),
                       static_cast<std::size_t>(PQgetlength(r_, row, col)));
  }
  std::int64_t integer(int row, int col) const { return std::stoll(text(row, col)); }
  double real(int row, int col) const { return std::stod(text(row, col)); }

 private:
  PGresult* r_;
};

class PostgresStore final : public Store {
 public:
  explicit PostgresStore(const std::string& uri) : uri_(uri), name_(withoutPassword(uri)) {
    conn_ = PQconnectdb(uri.c_str());
    if (PQstatus(conn_) != CONNECTION_OK) {
      const std::string why = conn_ ? PQerrorMessage(conn_) : "out of memory";
      PQfinish(conn_);
      conn_ = nullptr;
      throw Error(ErrorCode::kIo, "cannot connect to store '" + name_ + "': " + oneLine(why));
    }
    // The server's notices and warnings are not printed on stderr (libpq's default): what
    // fails reaches the caller as an Error with the server's reason in it.
    PQsetNoticeProcessor(
        conn_, [](void*, const char*) {}, nullptr);
    try {
      exec("SET client_min_messages = warning");  // no NOTICE for tables that exist
      exec("BEGIN");
      exec("SELECT pg_advisory_xact_lock(8128031)");  // one creator of the schema at a time
      exec(kSchema);
      Result v(query("SELECT version FROM octovk_schema", {}));
      if (v.rows() == 0) {
        exec("INSERT INTO octovk_schema VALUES (" + std::to_string(kSchemaVersion) + ")");
      } else if (v.integer(0, 0) != kSchemaVersion) {
        throw Error(ErrorCode::kInvalidArgument, "store '" + name_ + "' has schema version " +
                                                     v.text(0, 0) + ", this octovk reads version " +
                                                     std::to_string(kSchemaVersion));
      }
      exec("COMMIT");
    } catch (...) {
      PQfinish(conn_);
      throw;
    }
  }
  ~PostgresStore() override { PQfinish(conn_); }

  const std::string& location() const override { return name_; }

  std::vector<MapInfo> maps() override {
    std::vector<MapInfo> out;
    Result r(query("SELECT name FROM maps ORDER BY name", {}));
    for (int i = 0; i < r.rows(); ++i)
      if (auto info = map(r.text(i, 0))) out.push_back(*info);
    return out;
  }

  std::optional<MapInfo> map(const std::string& name) override {
    Result r(
        query("SELECT resolution, prob_hit, prob_miss, clamping_min, clamping_max, "
              "occupancy_threshold, tile_depth, tile_format, "
              "(SELECT count(*) FROM tiles t WHERE t.map = m.id), "
              "(SELECT coalesce(sum(length(body)), 0) FROM tiles t WHERE t.map = m.id), "
              "(SELECT count(*) FROM log l WHERE l.map = m.id), "
              "(SELECT coalesce(max(seq), 0) FROM log l WHERE l.map = m.id) "
              "FROM maps m WHERE name = $1",
              {name}));
    if (r.rows() == 0) return std::nullopt;
    MapInfo info;
    info.name = name;
    info.params.resolution = r.real(0, 0);
    info.params.prob_hit = r.real(0, 1);
    info.params.prob_miss = r.real(0, 2);
    info.params.clamping_min = r.real(0, 3);
    info.params.clamping_max = r.real(0, 4);
    info.params.occupancy_threshold = r.real(0, 5);
    info.tile_depth = static_cast<unsigned>(r.integer(0, 6));
    readTileFormat(info, r.integer(0, 7), "map '" + name + "' of store '" + name_ + "'");
    info.tiles = static_cast<std::uint64_t>(r.integer(0, 8));
    info.tile_bytes = static_cast<std::uint64_t>(r.integer(0, 9));
    info.scans = static_cast<std::uint64_t>(r.integer(0, 10));
    info.last_seq = static_cast<std::uint64_t>(r.integer(0, 11));
    return info;
  }

  bool createMap(const std::string& name, const MapParams& p) override {
    const auto num = [](double v) {
      char text[64];
      std::snprintf(text, sizeof(text), "%.17g", v);
      return std::string(text);
    };
    Result r(
        query("INSERT INTO maps (name, resolution, prob_hit, prob_miss, clamping_min, "
              "clamping_max, occupancy_threshold, tile_depth, tile_format) "
              "VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9) ON CONFLICT (name) DO NOTHING "
              "RETURNING id",
              {name, num(p.resolution), num(p.prob_hit), num(p.prob_miss), num(p.clamping_min),
               num(p.clamping_max), num(p.occupancy_threshold), std::to_string(kTileDepth),
               std::to_string(tileFormatOf(p.payload))}));
    return r.rows() == 1;
  }

  std::uint64_t lock(const std::string& name) override {
    unlock();
    exec("BEGIN");
    locked_ = true;
    try {
      return lastSeq(lockedMapId(name));
    } catch (...) {
      unlock();
      throw;
    }
  }

  void unlock() override {
    if (!locked_) return;
    locked_ = false;
    PQclear(PQexec(conn_, "ROLLBACK"));
  }

  std::vector<Tile> tiles(const std::string& name, std::uint64_t* last_seq) override {
    return inSnapshot([&] {
      const std::string id = mapId(name);
      std::vector<Tile> out = tilesAfter(id, 0, name);
      if (last_seq) *last_seq = lastSeq(id);
      return out;
    });
  }

  TileChanges changesSince(const std::string& name, std::uint64_t since) override {
    return inSnapshot([&] {
      const std::string id = mapId(name);
      TileChanges out;
      Result r(query("SELECT key FROM tiles WHERE map = $1 ORDER BY key", {id}));
      out.keys.reserve(static_cast<std::size_t>(r.rows()));
      for (int i = 0; i < r.rows(); ++i)
        out.keys.push_back(static_cast<std::uint64_t>(r.integer(i, 0)));
      out.changed = tilesAfter(id, since, name);
      out.last_seq = lastSeq(id);
      return out;
    });
  }

  bool waitForCommit(const std::string& name, double seconds) override {
    // LISTEN once; then a commit to any map wakes the wait, and one to this map ends it.
    if (!listening_ || listen_name_ != name) {
      listen_id_ = mapId(name);
      listen_name_ = name;
      if (!listening_) exec("LISTEN octovk_commit");
      listening_ = true;
    }
    const std::string& id = listen_id_;
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    for (;;) {
      bool ours = false;
      while (PGnotify* n = PQnotifies(conn_)) {
        ours = ours || id == n->extra;
        PQfreemem(n);
      }
      if (ours) return true;
      const double left =
          std::chrono::duration<double>(end - std::chrono::steady_clock::now()).count();
      if (left <= 0) return false;
      pollfd fd{PQsocket(conn_), POLLIN, 0};
      if (fd.fd < 0) return false;
      const int ready = ::poll(&fd, 1, static_cast<int>(std::ceil(left * 1000.0)));
      if (ready > 0 && PQconsumeInput(conn_) == 0)
        throw Error(ErrorCode::kIo, "store '" + name_ + "': waiting for commits: " +
                                        oneLine(PQerrorMessage(conn_)));
    }
  }

  std::vector<LogEntry> log(const std::string& name) override {
    Result r(query("SELECT seq, source, scan, time_us FROM log WHERE map = $1 ORDER BY seq",
                   {mapId(name)}));
    std::vector<LogEntry> out;
    for (int i = 0; i < r.rows(); ++i)
      out.push_back({static_cast<std::uint64_t>(r.integer(i, 0)), r.text(i, 1),
                     static_cast<std::uint64_t>(r.integer(i, 2)), r.integer(i, 3)});
    return out;
  }

  void commit(const std::string& name, std::span<const Tile> changed,
              std::span<const std::uint64_t> removed, const LogEntry& entry) override {
    if (!locked_) exec("BEGIN");
    locked_ = false;  // the transaction ends here, committed or rolled back
    try {
      const std::string id = lockedMapId(name);  // writers of one map take turns
      const std::uint64_t last = lastSeq(id);
      if (last + 1 != entry.seq)
        throw Error(ErrorCode::kInvalidArgument,
                    "map '" + name + "' of store '" + name_ + "' was changed by another writer (" +
                        "its last scan is " + std::to_string(last) + ", this run expected " +
                        std::to_string(entry.seq - 1) +
                        "); octovk does not merge concurrent writers yet: run them one after "
                        "the other");
      const std::string seq = std::to_string(entry.seq);
      // The tiles in statements of up to 1,000 rows: a round trip per statement, not per tile.
      constexpr std::size_t kRows = 1000;
      for (std::size_t first = 0; first < changed.size(); first += kRows) {
        const std::size_t rows = std::min(kRows, changed.size() - first);
        std::string sql = "INSERT INTO tiles (map, key, version, body) VALUES ";
        std::vector<std::string> keys(rows);
        std::vector<const char*> values = {id.c_str(), seq.c_str()};
        std::vector<int> lengths = {0, 0}, formats = {0, 0};
        for (std::size_t i = 0; i < rows; ++i) {
          const Tile& t = changed[first + i];
          keys[i] = std::to_string(static_cast<std::int64_t>(t.key));
          const std::string k = std::to_string(3 + 2 * i), b = std::to_string(4 + 2 * i);
          sql += (i == 0 ? "($1, $" : ", ($1, $") + k + ", $2, $" + b + ")";
          values.insert(values.end(), {keys[i].c_str(), t.body.data()});
          lengths.insert(lengths.end(), {0, static_cast<int>(t.body.size())});
          formats.insert(formats.end(), {0, 1});  // the body in binary
        }
        sql +=
            " ON CONFLICT (map, key) DO UPDATE SET version = EXCLUDED.version, "
            "body = EXCLUDED.body";
        PQclear(check(PQexecParams(conn_, sql.c_str(), static_cast<int>(values.size()), nullptr,
                                   values.data(), lengths.data(), formats.data(), 0),
                      "writing scan " + seq + " of map '" + name + "'"));
      }
      for (const std::uint64_t key : removed)
        PQclear(query("DELETE FROM tiles WHERE map = $1 AND key = $2",
                      {id, std::to_string(static_cast<std::int64_t>(key))}));
      PQclear(query(
          "INSERT INTO log (map, seq, source, scan, time_us) VALUES ($1,$2,$3,$4,$5)",
          {id, seq, entry.source, std::to_string(entry.scan), std::to_string(entry.time_us)}));
      // Followers listening are told at the commit (a notification is sent only if it commits).
      PQclear(query("SELECT pg_notify('octovk_commit', $1)", {id}));
      exec("COMMIT");
    } catch (...) {
      PQclear(PQexec(conn_, "ROLLBACK"));
      throw;
    }
  }

 private:
  // `read` in one REPEATABLE READ transaction, so that what it reads is one commit's (inside
  // lock()'s transaction when one is open: the map's row is locked there).
  template <class Read>
  auto inSnapshot(Read&& read) -> decltype(read()) {
    const bool own = !locked_;
    if (own) exec("BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY");
    try {
      auto out = read();
      if (own) exec("COMMIT");
      return out;
    } catch (...) {
      if (own) PQclear(PQexec(conn_, "ROLLBACK"));
      throw;
    }
  }

  // The tiles of map `id` written after scan `since` (0: every tile; versions start at 1), by key.
  std::vector<Tile> tilesAfter(const std::string& id, std::uint64_t since,
                               const std::string& name) {
    const std::string after = std::to_string(since);
    const char* values[] = {id.c_str(), after.c_str()};
    Result r(check(PQexecParams(conn_,
                                "SELECT key, body FROM tiles WHERE map = $1 AND version > $2 "
                                "ORDER BY key",
                                2, nullptr, values, nullptr, nullptr, /*binary results=*/1),
                   "reading the tiles of map '" + name + "'"));
    std::vector<Tile> out;
    out.reserve(static_cast<std::size_t>(r.rows()));
    for (int i = 0; i < r.rows(); ++i) {
      const std::string key = r.text(i, 0);  // int8, network order
      std::uint64_t k = 0;
      for (unsigned char c : key) k = (k << 8) | c;
      out.push_back({k, r.text(i, 1)});
    }
    return out;
  }

  // libpq's message on one line: its line breaks and indents as single spaces.
  static std::string oneLine(const std::string& text) {
    std::string out;
    for (const char c : text) {
      const bool space = c == '\n' || c == '\t' || c == ' ';
      if (space && (out.empty() || out.back() == ' ')) continue;
      out += space ? ' ' : c;
    }
    while (!out.empty() && out.back() == ' ') out.pop_back();
    return out;
  }

  // What a statement does, in words, for its error message (no SQL reaches the user).
  static std::string doing(std::string_view sql) {
    const auto has = [&](std::string_view part) { return sql.find(part) != sql.npos; };
    if (sql.starts_with("BEGIN")) return "starting a transaction";
    if (sql.starts_with("COMMIT")) return "committing";
    if (sql.starts_with("LISTEN")) return "listening for commits";
    if (has("pg_notify")) return "telling followers of the commit";
    if (has("pg_advisory") || has("octovk_schema") || sql.starts_with("CREATE") ||
        sql.starts_with("SET"))
      return "checking its schema";
    if (sql.starts_with("INSERT INTO tiles")) return "writing tiles";
    if (sql.starts_with("DELETE FROM tiles")) return "deleting tiles";
    if (sql.starts_with("INSERT INTO log")) return "writing the log row";
    if (sql.starts_with("INSERT INTO maps")) return "creating the map";
    if (has("FOR UPDATE")) return "taking the map's write lock";
    if (has("FROM tiles")) return "reading tiles";
    if (has("FROM log")) return "reading the log";
    if (has("FROM maps")) return "reading its maps";
    return "a query";
  }

  // `r`, or kIo saying what failed (`what`, in words) and why.
  PGresult* check(PGresult* r, const std::string& what) {
    const ExecStatusType status = PQresultStatus(r);
    if (status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK) return r;
    const std::string why = oneLine(r ? PQresultErrorMessage(r) : PQerrorMessage(conn_));
    PQclear(r);
    const bool lost = PQstatus(conn_) == CONNECTION_BAD;
    throw Error(ErrorCode::kIo,
                "store '" + name_ + "': " + what + " failed: " + why +
                    (lost ? " (the connection to the server is lost: check that the server runs "
                            "and can be reached; the store keeps every scan committed before)"
                          : ""));
  }

  void exec(const std::string& sql) { PQclear(check(PQexec(conn_, sql.c_str()), doing(sql))); }

  PGresult* query(const char* sql, const std::vector<std::string>& params) {
    std::vector<const char*> values;
    for (const std::string& p : params) values.push_back(p.c_str());
    return check(PQexecParams(conn_, sql, static_cast<int>(values.size()), nullptr, values.data(),
                              nullptr, nullptr, 0),
                 doing(sql));
  }

  // The map's id, its row locked until the transaction ends (SELECT ... FOR UPDATE).
  std::string lockedMapId(const std::string& name) {
    Result r(query("SELECT id FROM maps WHERE name = $1 FOR UPDATE", {name}));
    if (r.rows() == 0)
      throw Error(ErrorCode::kInvalidArgument, "store '" + name_ + "' holds no map '" + name + "'");
    return r.text(0, 0);
  }

  std::string mapId(const std::string& name) {
    Result r(query("SELECT id FROM maps WHERE name = $1", {name}));
    if (r.rows() == 0)
      throw Error(ErrorCode::kInvalidArgument, "store '" + name_ + "' holds no map '" + name +
                                                   "'; 'octovk store info " + name_ +
                                                   "' lists its maps");
    return r.text(0, 0);
  }

  std::uint64_t lastSeq(const std::string& id) {
    Result r(query("SELECT coalesce(max(seq), 0) FROM log WHERE map = $1", {id}));
    return static_cast<std::uint64_t>(r.integer(0, 0));
  }

  std::string uri_;
  std::string name_;
  PGconn* conn_ = nullptr;
  bool listening_ = false;               // LISTEN octovk_commit sent (waitForCommit)
  std::string listen_name_, listen_id_;  // the map waited for, and its id
  bool locked_ = false;                  // lock()'s transaction is open
};

}  // namespace

bool isPostgresLocation(const std::string& location) {
  return location.rfind("postgresql://", 0) == 0 || location.rfind("postgres://", 0) == 0;
}

std::unique_ptr<Store> openPostgresStore(const std::string& location) {
  return std::make_unique<PostgresStore>(location);
}

}  // namespace octovk::store
