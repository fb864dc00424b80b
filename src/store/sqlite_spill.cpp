// octovk::sqliteTileSpill: the tiles a map moved off the device (TileSpill), in a private
// temporary SQLite database. SQLite opens an empty file name as a temporary database on disk
// (its pages cached in memory until they exceed the cache), deleted when the connection closes.
#include <sqlite3.h>

#include <string>

#include "octovk/store.hpp"

namespace octovk {

namespace {

class SqliteTileSpill final : public TileSpill {
 public:
  SqliteTileSpill() {
    if (sqlite3_open_v2("", &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) !=
        SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      throw Error(ErrorCode::kIo, "tile spill: cannot make a temporary SQLite database (" + why +
                                      "); set SQLITE_TMPDIR to a writable folder");
    }
    exec(
        "PRAGMA journal_mode=OFF; PRAGMA synchronous=OFF;"
        "CREATE TABLE tiles (key INTEGER PRIMARY KEY, body BLOB NOT NULL);");
    put_ = prepare("INSERT OR REPLACE INTO tiles (key, body) VALUES (?1, ?2)");
    get_ = prepare("SELECT body FROM tiles WHERE key = ?1");
    erase_ = prepare("DELETE FROM tiles WHERE key = ?1");
  }
  ~SqliteTileSpill() override {
    sqlite3_finalize(put_);
    sqlite3_finalize(get_);
    sqlite3_finalize(erase_);
    sqlite3_close(db_);
  }
  SqliteTileSpill(const SqliteTileSpill&) = delete;
  SqliteTileSpill& operator=(const SqliteTileSpill&) = delete;

  void put(std::uint64_t key, const std::string& body) override {
    Reset reset{put_};
    sqlite3_bind_int64(put_, 1, static_cast<sqlite3_int64>(key));
    sqlite3_bind_blob(put_, 2, body.data(), static_cast<int>(body.size()), SQLITE_STATIC);
    if (sqlite3_step(put_) != SQLITE_DONE) fail("write a tile");
  }
  std::string get(std::uint64_t key) override {
    Reset reset{get_};
    sqlite3_bind_int64(get_, 1, static_cast<sqlite3_int64>(key));
    const int rc = sqlite3_step(get_);
    if (rc == SQLITE_DONE)
      throw Error(ErrorCode::kInternal,
                  "internal error: the tile spill holds no tile " + std::to_string(key));
    if (rc != SQLITE_ROW) fail("read a tile");
    const auto* bytes = static_cast<const char*>(sqlite3_column_blob(get_, 0));
    return std::string(bytes ? bytes : "", static_cast<std::size_t>(sqlite3_column_bytes(get_, 0)));
  }
  void erase(std::uint64_t key) override {
    Reset reset{erase_};
    sqlite3_bind_int64(erase_, 1, static_cast<sqlite3_int64>(key));
    if (sqlite3_step(erase_) != SQLITE_DONE) fail("delete a tile");
  }

 private:
  // Leaves a statement ready for its next use, whatever happened.
  struct Reset {
    sqlite3_stmt* stmt;
    ~Reset() {
      sqlite3_reset(stmt);
      sqlite3_clear_bindings(stmt);
    }
  };
  void exec(const char* sql) {
    if (sqlite3_exec(db_, sql, nullptr, nullptr, nullptr) != SQLITE_OK) fail("set up");
  }
  sqlite3_stmt* prepare(const char* sql) {
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db_, sql, -1, &stmt, nullptr) != SQLITE_OK) fail("set up");
    return stmt;
  }
  [[noreturn]] void fail(const char* what) {
    throw Error(ErrorCode::kIo, std::string("tile spill: cannot ") + what +
                                    " in its temporary SQLite database (" + sqlite3_errmsg(db_) +
                                    "); is its folder (SQLITE_TMPDIR or TMPDIR) full?");
  }

  sqlite3* db_ = nullptr;
  sqlite3_stmt* put_ = nullptr;
  sqlite3_stmt* get_ = nullptr;
  sqlite3_stmt* erase_ = nullptr;
};

}  // namespace

std::shared_ptr<TileSpill> sqliteTileSpill() { return std::make_shared<SqliteTileSpill>(); }

}  // namespace octovk
