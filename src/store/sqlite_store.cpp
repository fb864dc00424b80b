// The SQLite back end: one file, WAL journal (readers see the last committed scan while a writer
// works), synchronous=NORMAL (a killed process loses no commit; a power loss may lose the last
// ones, never the file's consistency).
#include <sqlite3.h>

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <memory>
#include <mutex>
#include <thread>
#include <unordered_map>
#include <utility>

#include "store/store.hpp"

namespace octovk::store {

namespace {

// The schema; user_version says which (kSchemaVersion).
constexpr int kSchemaVersion = 1;
constexpr const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS maps (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  resolution REAL NOT NULL,
  prob_hit REAL NOT NULL,
  prob_miss REAL NOT NULL,
  clamping_min REAL NOT NULL,
  clamping_max REAL NOT NULL,
  occupancy_threshold REAL NOT NULL,
  tile_depth INTEGER NOT NULL,
  tile_format INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS tiles (
  map INTEGER NOT NULL REFERENCES maps(id),
  key INTEGER NOT NULL,
  version INTEGER NOT NULL,
  body BLOB NOT NULL,
  PRIMARY KEY (map, key)) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS log (
  map INTEGER NOT NULL REFERENCES maps(id),
  seq INTEGER NOT NULL,
  source TEXT NOT NULL,
  scan INTEGER NOT NULL,
  time_us INTEGER NOT NULL,
  PRIMARY KEY (map, seq)) WITHOUT ROWID;
)sql";

class Statement {
 public:
  Statement(sqlite3* db, const char* sql, const std::string& where) : where_(where) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK)
      throw Error(ErrorCode::kIo, where_ + ": " + sqlite3_errmsg(db));
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  /// Ends a read (a kept statement holds no snapshot between uses).
  void done() { sqlite3_reset(stmt_); }
  /// For another use of a kept statement: its bindings cleared, its errors naming `where`.
  Statement& reuse(const std::string& where) {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
    where_ = where;
    return *this;
  }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& bind(int i, std::int64_t v) {
    check(sqlite3_bind_int64(stmt_, i, v));
    return *this;
  }
  Statement& bind(int i, double v) {
    check(sqlite3_bind_double(stmt_, i, v));
    return *this;
  }
  Statement& bind(int i, const std::string& v) {
    check(sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  Statement& blob(int i, const std::string& v) {
    check(sqlite3_bind_blob(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  /// True while a row is there.
  bool step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw Error(ErrorCode::kIo, where_ + ": " + sqlite3_errmsg(sqlite3_db_handle(stmt_)));
  }
  void run() {
    step();
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  std::int64_t integer(int c) const { return sqlite3_column_int64(stmt_, c); }
  double real(int c) const { return sqlite3_column_double(stmt_, c); }
  std::string text(int c) const {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_blob(stmt_, c));
    return p ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(stmt_, c)))
             : std::string();
  }

 private:
  void check(int rc) const {
    if (rc != SQLITE_OK)
      throw Error(ErrorCode::kIo, where_ + ": " + sqlite3_errmsg(sqlite3_db_handle(stmt_)));
  }
  sqlite3_stmt* stmt_ = nullptr;
  std::string where_;
};

// The WAL's checkpoints, mostly off the writer's thread. SQLite's own (wal_autocheckpoint, 1000
// frames: 16 MB of 16 KiB pages) runs in the commit that fills the WAL, and syncs those 16 MB to
// disk there: 12-19 ms each on the test machine (strace), every 50th scan of FR-079 at 0.05 m, a
// tenth of a run's time in the commit's thread. Here a thread with a connection of its own does
// that work (SQLITE_CHECKPOINT_PASSIVE: beside the writer, which goes on committing); the
// writer's next commit then checkpoints the few frames committed meanwhile itself, so that every
// frame is copied before its next transaction begins: only then does SQLite start the WAL over,
// and the file stays as small as with SQLite's own checkpoints.
class WalCheckpointer {
 public:
  // Frames in the WAL that wake the thread: SQLite's default.
  static constexpr int kFrames = 1000;
  // Frames left uncopied that the writer's checkpoint may take.
  static constexpr int kLeftFrames = 64;

  // Starts on store `path`, whose writer connection is `writer` (its WAL hook becomes this);
  // nothing when the connection cannot be opened or SQLite has no threads (the writer keeps
  // SQLite's own checkpoints).
  static std::unique_ptr<WalCheckpointer> start(sqlite3* writer, const std::string& path) {
    if (sqlite3_threadsafe() == 0) return nullptr;  // a SQLite built without threads
    sqlite3* db = nullptr;
    if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX, nullptr) !=
            SQLITE_OK ||
        sqlite3_exec(db, "PRAGMA synchronous = NORMAL", nullptr, nullptr, nullptr) != SQLITE_OK) {
      sqlite3_close(db);
      return nullptr;
    }
    auto c = std::unique_ptr<WalCheckpointer>(new WalCheckpointer(db));
    sqlite3_wal_hook(writer, &WalCheckpointer::hook, c.get());
    return c;
  }

  // After the writer's connection is closed (or its hook is reset): the thread ends, and the
  // connection closes, the last one of this process, with a checkpoint of what is left.
  ~WalCheckpointer() {
    {
      const std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_one();
    thread_.join();
    sqlite3_close(db_);
  }

  WalCheckpointer(const WalCheckpointer&) = delete;
  WalCheckpointer& operator=(const WalCheckpointer&) = delete;

 private:
  enum class State { kIdle, kWanted, kRunning, kDone };

  explicit WalCheckpointer(sqlite3* db) : db_(db), thread_([this] { run(); }) {}

  // The writer's WAL hook, after each commit, on its thread: `frames` are in the WAL.
  static int hook(void* self, sqlite3* writer, const char* schema, int frames) {
    static_cast<WalCheckpointer*>(self)->committed(writer, schema, frames);
    return SQLITE_OK;
  }

  void committed(sqlite3* writer, const char* schema, int frames) {
    std::unique_lock lock(mutex_);
    if (state_ == State::kDone) {
      state_ = State::kIdle;
      lock.unlock();
      // The rest, a few commits' frames (errors: the next checkpoint tries again).
      sqlite3_wal_checkpoint_v2(writer, schema, SQLITE_CHECKPOINT_PASSIVE, nullptr, nullptr);
      return;
    }
    if (state_ != State::kIdle || frames < kFrames) return;
    state_ = State::kWanted;
    lock.unlock();
    wake_.notify_one();
  }

  void run() {
    for (;;) {
      {
        std::unique_lock lock(mutex_);
        wake_.wait(lock, [&] { return stop_ || state_ == State::kWanted; });
        if (stop_) return;
        state_ = State::kRunning;
      }
      // Again while the writer committed more than a few frames meanwhile (a pass's sync took
      // 12-19 ms, while FR-079 committed about 20 frames a scan), so that the writer's own
      // checkpoint is short. Errors (another process checkpointing, a full disk): the writer's
      // checkpoint copies what this did not.
      for (int pass = 0; pass < 3; ++pass) {
        int frames = 0, copied = 0;
        if (sqlite3_wal_checkpoint_v2(db_, nullptr, SQLITE_CHECKPOINT_PASSIVE, &frames, &copied) !=
                SQLITE_OK ||
            frames - copied <= kLeftFrames)
          break;
      }
      const std::lock_guard lock(mutex_);
      state_ = State::kDone;
    }
  }

  sqlite3* db_;
  std::mutex mutex_;
  std::condition_variable wake_;
  State state_ = State::kIdle;
  bool stop_ = false;
  std::thread thread_;  // last: it starts once the members above are made
};

class SqliteStore final : public Store {
 public:
  SqliteStore(const std::string& path, bool create) : path_(path) {
    try {
      openAndCheck(create);
    } catch (...) {
      kept_.clear();
      sqlite3_close(db_);
      throw;
    }
  }

  void openAndCheck(bool create) {
    const std::string& path = path_;
    namespace fs = std::filesystem;
    std::error_code ec;
    if (!create && !fs::exists(path, ec))
      throw Error(ErrorCode::kInvalidArgument,
                  "store '" + path + "' does not exist; 'octovk integrate INPUT --store " + path +
                      "' creates it");
    const int flags =
        SQLITE_OPEN_READWRITE | (create ? SQLITE_OPEN_CREATE : 0) | SQLITE_OPEN_NOMUTEX;
    if (sqlite3_open_v2(path.c_str(), &db_, flags, nullptr) != SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      db_ = nullptr;
      throw Error(ErrorCode::kIo, "cannot open store '" + path + "': " + why +
                                      "; check that its folder exists and can be written");
    }
    sqlite3_busy_timeout(db_, 10000);  // another process's commit: wait, do not fail
    exec("PRAGMA foreign_keys = ON");
    // The check and the creation in one transaction (the write lock when creating): two runs
    // creating one store at once take turns, and neither sees the other's half-made schema.
    const auto counts = [&](int* version, std::int64_t* objects) {
      Statement v(db_, "PRAGMA user_version",
                  where("reading its schema version (is it the SQLite file 'octovk integrate "
                        "--store' wrote?)"));
      *version = v.step() ? static_cast<int>(v.integer(0)) : 0;
      Statement o(db_, "SELECT count(*) FROM sqlite_master", where("reading its tables"));
      *objects = o.step() ? o.integer(0) : 0;
    };
    int version = 0;
    std::int64_t objects = 0;
    // 16 KiB pages for a new file (before its first table; an existing file keeps its own): a
    // tile body is about 1.3 KB, and the tiles table (WITHOUT ROWID) keeps rows in its leaves,
    // of which SQLite's default 4 KiB pages held two or three (a scan's commit on FR-079 at
    // 0.05 m: 1.5 ms instead of 2.2).
    if (create) exec("PRAGMA page_size = 16384");
    exec(create ? "BEGIN IMMEDIATE" : "BEGIN");
    try {
      counts(&version, &objects);
      if (version == 0) {
        // Not an octovk store yet: refuse a database that holds tables of something else.
        if (objects != 0 || !create)
          throw Error(ErrorCode::kInvalidArgument,
                      "'" + path + "' is no octovk store (" +
                          (objects != 0 ? "an SQLite database of something else" : "empty") +
                          "); give the file 'octovk integrate ... --store' wrote");
        exec(kSchema);
        exec("PRAGMA user_version = " + std::to_string(kSchemaVersion));
      } else if (version != kSchemaVersion) {
        throw Error(ErrorCode::kInvalidArgument,
                    "store '" + path + "' has schema version " + std::to_string(version) +
                        ", this octovk reads version " + std::to_string(kSchemaVersion) +
                        "; use the octovk that wrote it");
      }
      exec("COMMIT");
    } catch (...) {
      sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
      throw;
    }
    useWal();
    exec("PRAGMA synchronous = NORMAL");
  }
  ~SqliteStore() override {
    kept_.clear();  // finalized before the connection closes
    sqlite3_close(db_);
    checkpointer_.reset();  // after the writer's connection: its close checkpoints the rest
  }

  const std::string& location() const override { return path_; }

  std::vector<MapInfo> maps() override {
    std::vector<MapInfo> out;
    Statement s(db_, "SELECT name FROM maps ORDER BY name", where("listing its maps"));
    std::vector<std::string> names;
    while (s.step()) names.push_back(s.text(0));
    for (const std::string& name : names)
      if (auto info = map(name)) out.push_back(*info);
    return out;
  }

  std::optional<MapInfo> map(const std::string& name) override {
    Statement s(db_,
                "SELECT resolution, prob_hit, prob_miss, clamping_min, clamping_max, "
                "occupancy_threshold, tile_depth, tile_format, "
                "(SELECT count(*) FROM tiles t WHERE t.map = m.id), "
                "(SELECT coalesce(sum(length(body)), 0) FROM tiles t WHERE t.map = m.id), "
                "(SELECT count(*) FROM log l WHERE l.map = m.id), "
                "(SELECT coalesce(max(seq), 0) FROM log l WHERE l.map = m.id) "
                "FROM maps m WHERE name = ?",
                where("reading map '" + name + "'"));
    s.bind(1, name);
    if (!s.step()) return std::nullopt;
    MapInfo info;
    info.name = name;
    info.params.resolution = s.real(0);
    info.params.prob_hit = s.real(1);
    info.params.prob_miss = s.real(2);
    info.params.clamping_min = s.real(3);
    info.params.clamping_max = s.real(4);
    info.params.occupancy_threshold = s.real(5);
    info.tile_depth = static_cast<unsigned>(s.integer(6));
    readTileFormat(info, s.integer(7), "map '" + name + "' of store '" + path_ + "'");
    info.tiles = static_cast<std::uint64_t>(s.integer(8));
    info.tile_bytes = static_cast<std::uint64_t>(s.integer(9));
    info.scans = static_cast<std::uint64_t>(s.integer(10));
    info.last_seq = static_cast<std::uint64_t>(s.integer(11));
    return info;
  }

  bool createMap(const std::string& name, const MapParams& p) override {
    Statement s(db_,
                "INSERT OR IGNORE INTO maps (name, resolution, prob_hit, prob_miss, clamping_min, "
                "clamping_max, occupancy_threshold, tile_depth, tile_format) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                where("creating map '" + name + "'"));
    s.bind(1, name)
        .bind(2, p.resolution)
        .bind(3, p.prob_hit)
        .bind(4, p.prob_miss)
        .bind(5, p.clamping_min)
        .bind(6, p.clamping_max)
        .bind(7, p.occupancy_threshold)
        .bind(8, std::int64_t{kTileDepth})
        .bind(9, std::int64_t{tileFormatOf(p.payload)});
    s.run();
    return sqlite3_changes(db_) == 1;
  }

  std::uint64_t lock(const std::string& name) override {
    unlock();
    run("BEGIN IMMEDIATE", "taking the write lock failed");  // another writer waits (busy timeout)
    locked_ = true;
    try {
      return lastSeq(mapId(name));
    } catch (...) {
      unlock();
      throw;
    }
  }

  void unlock() override {
    if (!locked_) return;
    locked_ = false;
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }

  std::vector<Tile> tiles(const std::string& name, std::uint64_t* last_seq) override {
    return inSnapshot([&] {
      const std::int64_t id = mapId(name);
      std::vector<Tile> out = tilesAfter(id, 0, name);
      if (last_seq) *last_seq = lastSeq(id);
      return out;
    });
  }

  TileChanges changesSince(const std::string& name, std::uint64_t since) override {
    return inSnapshot([&] {
      TileChanges out;
      const std::int64_t id = mapId(name);
      Statement s(db_, "SELECT key FROM tiles WHERE map = ? ORDER BY key",
                  where("reading the tile keys of map '" + name + "'"));
      s.bind(1, id);
      while (s.step()) out.keys.push_back(static_cast<std::uint64_t>(s.integer(0)));
      out.changed = tilesAfter(id, since, name);
      out.last_seq = lastSeq(id);
      return out;
    });
  }

  std::vector<LogEntry> log(const std::string& name) override {
    std::vector<LogEntry> out;
    Statement s(db_, "SELECT seq, source, scan, time_us FROM log WHERE map = ? ORDER BY seq",
                where("reading the log of map '" + name + "'"));
    s.bind(1, mapId(name));
    while (s.step())
      out.push_back({static_cast<std::uint64_t>(s.integer(0)), s.text(1),
                     static_cast<std::uint64_t>(s.integer(2)), s.integer(3)});
    return out;
  }

  void commit(const std::string& name, std::span<const Tile> changed,
              std::span<const std::uint64_t> removed, const LogEntry& entry) override {
    // The WAL's checkpoints on a thread of their own, from a writer's first commit on (a reader
    // needs none).
    if (wal_ && !checkpointer_tried_) {
      checkpointer_tried_ = true;  // once: where it cannot start, SQLite's own checkpoints stay
      checkpointer_ = WalCheckpointer::start(db_, path_);
    }
    if (!locked_) run("BEGIN IMMEDIATE", "taking the write lock failed");  // another writer waits
    locked_ = false;  // the transaction ends here, committed or rolled back
    try {
      const std::int64_t id = mapId(name);
      const std::uint64_t last = lastSeq(id);
      if (last + 1 != entry.seq)
        throw Error(ErrorCode::kInvalidArgument,
                    "map '" + name + "' of store '" + path_ + "' was changed by another writer (" +
                        "its last scan is " + std::to_string(last) + ", this run expected " +
                        std::to_string(entry.seq - 1) +
                        "); octovk does not merge concurrent writers yet: run them one after "
                        "the other");
      const std::string at =
          where("writing scan " + std::to_string(entry.seq) + " of map '" + name + "'");
      // An upsert updates the row in its page; INSERT OR REPLACE deleted and inserted it, which
      // rebalanced the tree's leaves: 584 MB written for FR-079's first 500 scans at 0.05 m
      // against 162 MB, and a fifth more of the writer's CPU time.
      Statement& put = kept(
          "INSERT INTO tiles (map, key, version, body) VALUES (?,?,?,?) "
          "ON CONFLICT (map, key) DO UPDATE SET version = excluded.version, body = excluded.body",
          at);
      for (const Tile& t : changed) {
        put.bind(1, id).bind(2, static_cast<std::int64_t>(t.key));
        put.bind(3, static_cast<std::int64_t>(entry.seq)).blob(4, t.body);
        put.run();
      }
      Statement& del = kept("DELETE FROM tiles WHERE map = ? AND key = ?", at);
      for (const std::uint64_t key : removed) {
        del.bind(1, id).bind(2, static_cast<std::int64_t>(key));
        del.run();
      }
      Statement& row =
          kept("INSERT INTO log (map, seq, source, scan, time_us) VALUES (?,?,?,?,?)", at);
      row.bind(1, id).bind(2, static_cast<std::int64_t>(entry.seq)).bind(3, entry.source);
      row.bind(4, static_cast<std::int64_t>(entry.scan)).bind(5, entry.time_us);
      row.run();
      run("COMMIT", "committing failed");
    } catch (...) {
      sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
      throw;
    }
  }

 private:
  std::string where(const std::string& what) const { return "store '" + path_ + "': " + what; }

  // `read` in one read transaction, so that what it reads is one commit's (inside lock()'s
  // transaction when one is open).
  template <class Read>
  auto inSnapshot(Read&& read) -> decltype(read()) {
    const bool own = !locked_;
    if (own) exec("BEGIN");
    try {
      auto out = read();
      if (own) exec("COMMIT");
      return out;
    } catch (...) {
      if (own) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
      throw;
    }
  }

  // The tiles of map `id` written after scan `since` (0: every tile; versions start at 1), by key.
  std::vector<Tile> tilesAfter(std::int64_t id, std::uint64_t since, const std::string& name) {
    std::vector<Tile> out;
    Statement s(db_, "SELECT key, body FROM tiles WHERE map = ? AND version > ? ORDER BY key",
                where("reading the tiles of map '" + name + "'"));
    s.bind(1, id).bind(2, static_cast<std::int64_t>(since));
    while (s.step()) out.push_back({static_cast<std::uint64_t>(s.integer(0)), s.text(1)});
    return out;
  }

  // WAL (readers see the last commit while a writer works), once the file is known to be an
  // octovk store. Changing the journal mode needs the file to itself, which the busy timeout does
  // not wait for: a run that finds another at work tries for a while, and otherwise goes on in
  // the rollback journal (as correct, with readers and writers taking turns) for a later run to
  // change.
  void useWal() {
    for (int attempt = 0; attempt < 40; ++attempt) {
      {
        Statement mode(db_, "PRAGMA journal_mode", where("reading its journal mode"));
        if (mode.step() && mode.text(0) == "wal") {
          wal_ = true;
          return;
        }
      }  // finished: no read lock held while the mode changes
      if (attempt > 0) std::this_thread::sleep_for(std::chrono::milliseconds(25));
      sqlite3_exec(db_, "PRAGMA journal_mode = WAL", nullptr, nullptr, nullptr);
    }
  }

  void exec(const std::string& sql) {
    char* message = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &message) != SQLITE_OK) {
      const std::string why = message ? message : sqlite3_errmsg(db_);
      sqlite3_free(message);
      // In words (no SQL reaches the user): the transaction's steps, else the file's set-up.
      const char* doing = sql.starts_with("BEGIN IMMEDIATE") ? "taking the write lock"
                          : sql.starts_with("BEGIN")         ? "starting a transaction"
                          : sql.starts_with("COMMIT")        ? "committing"
                                                             : "setting up the file";
      throw Error(ErrorCode::kIo, where(std::string(doing) + " failed: " + why));
    }
  }

  std::int64_t mapId(const std::string& name) {
    Statement& s = kept("SELECT id FROM maps WHERE name = ?", where("finding map '" + name + "'"));
    s.bind(1, name);
    if (!s.step())
      throw Error(ErrorCode::kInvalidArgument, "store '" + path_ + "' holds no map '" + name +
                                                   "'; 'octovk store info " + path_ +
                                                   "' lists its maps");
    const std::int64_t id = s.integer(0);
    s.done();
    return id;
  }

  std::uint64_t lastSeq(std::int64_t id) {
    Statement& s =
        kept("SELECT coalesce(max(seq), 0) FROM log WHERE map = ?", where("reading the log"));
    s.bind(1, id);
    const std::uint64_t last = s.step() ? static_cast<std::uint64_t>(s.integer(0)) : 0;
    s.done();
    return last;
  }

  // The statement of `sql` (a literal), prepared at its first use and kept: a scan's commit
  // runs the same few statements every time. Its errors name `where`.
  Statement& kept(const char* sql, const std::string& where) {
    std::unique_ptr<Statement>& s = kept_[sql];
    if (!s) s = std::make_unique<Statement>(db_, sql, where);
    return s->reuse(where);
  }
  // A kept statement without results, run ("BEGIN IMMEDIATE", "COMMIT"); its error says `doing`.
  void run(const char* sql, const char* doing) { kept(sql, where(doing)).run(); }

  std::string path_;
  sqlite3* db_ = nullptr;
  bool locked_ = false;  // lock()'s transaction is open
  bool wal_ = false;     // in WAL mode (useWal)
  std::unordered_map<const char*, std::unique_ptr<Statement>> kept_;
  std::unique_ptr<WalCheckpointer> checkpointer_;  // from the first commit on, in WAL mode
  bool checkpointer_tried_ = false;
};

}  // namespace

std::unique_ptr<Store> Store::open(const std::string& location, bool create) {
  if (isPostgresLocation(location)) return openPostgresStore(location);
  return std::make_unique<SqliteStore>(location, create);
}

}  // namespace octovk::store
