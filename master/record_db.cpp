#include "record_db.hpp"

#include <sqlite3.h>

#include <string>

namespace ev3master {

namespace {

// Schema 2. Each migration takes a file of schema i to schema i + 1 (kMigrations[0]: an empty file
// to schema 1); open() runs those a file lacks, in one transaction, and sets user_version.
const char* const kMigrations[] = {
    R"sql(
CREATE TABLE robots (
  id            INTEGER PRIMARY KEY,  -- the id the master assigned
  announced     INTEGER NOT NULL,     -- the temporary (or previous) id it announced
  address       TEXT    NOT NULL,     -- host:port it was last registered from
  first_seen_ms INTEGER NOT NULL,     -- wall clock, ms since 1970
  last_seen_ms  INTEGER NOT NULL
);
CREATE TABLE states (
  row   INTEGER PRIMARY KEY,
  t_ms  INTEGER NOT NULL,
  agent INTEGER NOT NULL,
  state TEXT    NOT NULL              -- a lifecycle state from its PING, SYNCED, or LOST
);
CREATE TABLE commands (
  row         INTEGER PRIMARY KEY,
  sent_ms     INTEGER NOT NULL,
  agent       INTEGER NOT NULL,
  command     TEXT    NOT NULL,       -- BEHAVIOUR, START, PAUSE, ...
  args        TEXT    NOT NULL,       -- BEHAVIOUR's name and key=value arguments, space-separated
  answer      TEXT,                   -- acked, refused, timed_out; NULL: no answer (yet)
  reason      TEXT,                   -- a refusal's reason
  answered_ms INTEGER
);
CREATE TABLE reports (
  row   INTEGER PRIMARY KEY,
  t_ms  INTEGER NOT NULL,
  agent INTEGER NOT NULL,
  seq   INTEGER,                      -- the agent's report number; NULL: a report sent unnumbered
  type  TEXT    NOT NULL,             -- SENSOR_VALUE, ACTION_OK, ACTION_INTERR, ACTION_ERR, EVENT
  text  TEXT    NOT NULL,             -- its parameters joined by ':'
  UNIQUE (agent, seq)
);
CREATE TABLE reports_missing (
  row   INTEGER PRIMARY KEY,
  t_ms  INTEGER NOT NULL,
  agent INTEGER NOT NULL,
  first INTEGER NOT NULL,
  last  INTEGER NOT NULL,
  kind  TEXT    NOT NULL CHECK (kind IN ('dropped', 'skipped')),
  UNIQUE (agent, first)
);
CREATE TABLE epochs (
  row     INTEGER PRIMARY KEY,
  t_ms    INTEGER NOT NULL,
  epoch   INTEGER NOT NULL,
  role    TEXT    NOT NULL,           -- the PC's election role: MASTER, CANDIDATE
  members TEXT    NOT NULL            -- the membership it published, ids space-separated
);
)sql",
    // Schema 2: the model each robot announced.
    R"sql(
ALTER TABLE robots ADD COLUMN model TEXT;  -- the model it announced in AGENT (NULL: not known)
)sql",
    // Schema 3: the devices of its model each robot announced.
    R"sql(
ALTER TABLE robots ADD COLUMN devices TEXT;  -- JSON array of the devices it announced in AGENT (NULL: not known)
)sql",
};
static_assert(sizeof kMigrations / sizeof kMigrations[0] == RecordDb::kSchema, "one migration per schema");

std::string text_of(sqlite3* db) { return db != nullptr ? sqlite3_errmsg(db) : "out of memory"; }

}  // namespace

RecordDb::~RecordDb() { close(); }

std::string RecordDb::error(const std::string& what) const { return what + ": " + text_of(db_); }

bool RecordDb::exec(const char* sql) { return sqlite3_exec(db_, sql, nullptr, nullptr, nullptr) == SQLITE_OK; }

sqlite3_stmt* RecordDb::prepare(const char* sql) {
  sqlite3_stmt* s = nullptr;
  if (sqlite3_prepare_v3(db_, sql, -1, SQLITE_PREPARE_PERSISTENT, &s, nullptr) != SQLITE_OK) return nullptr;
  return s;
}

std::string RecordDb::open(const std::string& path) {
  const std::string bad = "bad value for --db: " + path;
  if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) != SQLITE_OK) {
    std::string e = bad + ": " + text_of(db_);
    close();
    return e;
  }
  sqlite3_busy_timeout(db_, 2000);  // a reader (ev3-fleet) holding the file for a moment
  // Reading the header is the first access: a file that is no database fails here.
  int app = 0, version = 0, objects = 0;
  sqlite3_stmt* s = nullptr;
  auto read_int = [&](const char* sql, int& out) {
    if (sqlite3_prepare_v2(db_, sql, -1, &s, nullptr) != SQLITE_OK) return false;
    const bool ok = sqlite3_step(s) == SQLITE_ROW;
    if (ok) out = sqlite3_column_int(s, 0);
    sqlite3_finalize(s);
    return ok;
  };
  if (!read_int("PRAGMA application_id", app) || !read_int("PRAGMA user_version", version) ||
      !read_int("SELECT count(*) FROM sqlite_schema", objects)) {
    std::string e = bad + " is not a record: " + text_of(db_);
    close();
    return e;
  }
  if (objects > 0 && app != kApplicationId) {
    close();
    return bad + " is another program's SQLite database (application_id " + std::to_string(app) +
           ", not ev3-master's " + std::to_string(kApplicationId) + ")";
  }
  if (version > kSchema) {
    close();
    return bad + " has schema " + std::to_string(version) + ", newer than this ev3-master's " +
           std::to_string(kSchema) + " (use a newer ev3-master)";
  }
  if (!exec("PRAGMA journal_mode=WAL") || !exec("PRAGMA synchronous=NORMAL") || !exec("PRAGMA foreign_keys=ON")) {
    std::string e = error(bad);
    close();
    return e;
  }
  if (version < kSchema) {
    bool ok = exec("BEGIN IMMEDIATE");
    for (int v = version; ok && v < kSchema; ++v) ok = exec(kMigrations[v]);
    const std::string set = "PRAGMA application_id=" + std::to_string(kApplicationId) +
                            "; PRAGMA user_version=" + std::to_string(kSchema);
    ok = ok && exec(set.c_str()) && exec("COMMIT");
    if (!ok) {
      std::string e = error(bad + ": cannot write its schema");
      exec("ROLLBACK");
      close();
      return e;
    }
    opened_ = version == 0 ? "created (schema " + std::to_string(kSchema) + ")"
                           : "migrated from schema " + std::to_string(version) + " to " + std::to_string(kSchema);
  } else {
    int reports = 0;
    read_int("SELECT count(*) FROM reports", reports);
    opened_ = "continued (schema " + std::to_string(kSchema) + ", " + std::to_string(reports) + " reports)";
  }
  robot_ = prepare(
      "INSERT INTO robots (id, announced, address, first_seen_ms, last_seen_ms, model, devices) VALUES (?1, ?2, ?3, "
      "?4, ?4, nullif(?5, ''), nullif(?6, '')) ON CONFLICT (id) DO UPDATE SET announced = ?2, address = ?3, "
      "last_seen_ms = ?4, model = coalesce(nullif(?5, ''), model), devices = coalesce(nullif(?6, ''), devices)");
  heard_ = prepare("UPDATE robots SET last_seen_ms = max(last_seen_ms, ?2) WHERE id = ?1");
  state_ = prepare("INSERT INTO states (t_ms, agent, state) VALUES (?1, ?2, ?3)");
  sent_ = prepare("INSERT INTO commands (sent_ms, agent, command, args) VALUES (?1, ?2, ?3, ?4)");
  answered_ = prepare("UPDATE commands SET answer = ?3, reason = ?4, answered_ms = ?1 WHERE row = ?2");
  report_ = prepare("INSERT OR IGNORE INTO reports (t_ms, agent, seq, type, text) VALUES (?1, ?2, ?3, ?4, ?5)");
  missing_ = prepare(
      "INSERT OR IGNORE INTO reports_missing (t_ms, agent, first, last, kind) VALUES (?1, ?2, ?3, ?4, ?5)");
  epoch_ = prepare("INSERT INTO epochs (t_ms, epoch, role, members) VALUES (?1, ?2, ?3, ?4)");
  for (sqlite3_stmt* p : {robot_, heard_, state_, sent_, answered_, report_, missing_, epoch_})
    if (p == nullptr) {
      std::string e = error(bad + ": cannot prepare its statements");
      close();
      return e;
    }
  return {};
}

bool RecordDb::begin() {
  if (db_ == nullptr) return false;
  if (!in_tx_) {
    if (!exec("BEGIN")) {
      if (failed_.empty()) failed_ = error("cannot begin a transaction");
      return false;
    }
    in_tx_ = true;
  }
  return true;
}

void RecordDb::step(sqlite3_stmt* s) {
  if (sqlite3_step(s) != SQLITE_DONE && failed_.empty()) failed_ = error("cannot write a row");
  sqlite3_reset(s);
  sqlite3_clear_bindings(s);
}

namespace {
void bind(sqlite3_stmt* s, int i, std::int64_t v) { sqlite3_bind_int64(s, i, v); }
void bind(sqlite3_stmt* s, int i, const std::string& v) {
  sqlite3_bind_text(s, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
}
}  // namespace

void RecordDb::robot_seen(std::uint16_t id, std::uint16_t announced, const std::string& address,
                          const std::string& model, const std::string& devices, std::int64_t t) {
  if (!begin()) return;
  bind(robot_, 1, id);
  bind(robot_, 2, announced);
  bind(robot_, 3, address);
  bind(robot_, 4, t);
  bind(robot_, 5, model);
  bind(robot_, 6, devices);
  step(robot_);
}

void RecordDb::robots_heard(std::uint16_t id, std::int64_t t) {
  if (!begin()) return;
  bind(heard_, 1, id);
  bind(heard_, 2, t);
  step(heard_);
}

void RecordDb::state(std::uint16_t id, const std::string& state, std::int64_t t) {
  if (!begin()) return;
  bind(state_, 1, t);
  bind(state_, 2, id);
  bind(state_, 3, state);
  step(state_);
  robots_heard(id, t);
}

std::int64_t RecordDb::command_sent(std::uint16_t id, const std::string& command, const std::string& args,
                                    std::int64_t t) {
  if (!begin()) return 0;
  bind(sent_, 1, t);
  bind(sent_, 2, id);
  bind(sent_, 3, command);
  bind(sent_, 4, args);
  step(sent_);
  return sqlite3_last_insert_rowid(db_);
}

void RecordDb::command_answered(std::int64_t row, const std::string& answer, const std::string& reason, std::int64_t t) {
  if (!begin() || row == 0) return;
  bind(answered_, 1, t);
  bind(answered_, 2, row);
  bind(answered_, 3, answer);
  if (!reason.empty()) bind(answered_, 4, reason);
  step(answered_);
}

void RecordDb::report(std::uint16_t id, std::uint32_t seq, const std::string& type, const std::string& text,
                      std::int64_t t) {
  if (!begin()) return;
  bind(report_, 1, t);
  bind(report_, 2, id);
  if (seq != 0) bind(report_, 3, static_cast<std::int64_t>(seq));
  bind(report_, 4, type);
  bind(report_, 5, text);
  step(report_);
  robots_heard(id, t);
}

void RecordDb::reports_missing(std::uint16_t id, std::uint32_t first, std::uint32_t last, const std::string& kind,
                               std::int64_t t) {
  if (!begin()) return;
  bind(missing_, 1, t);
  bind(missing_, 2, id);
  bind(missing_, 3, static_cast<std::int64_t>(first));
  bind(missing_, 4, static_cast<std::int64_t>(last));
  bind(missing_, 5, kind);
  step(missing_);
}

void RecordDb::epoch(std::uint32_t epoch, const std::string& role, const std::string& members, std::int64_t t) {
  if (!begin()) return;
  bind(epoch_, 1, t);
  bind(epoch_, 2, static_cast<std::int64_t>(epoch));
  bind(epoch_, 3, role);
  bind(epoch_, 4, members);
  step(epoch_);
}

std::string RecordDb::commit() {
  if (!in_tx_) return {};
  in_tx_ = false;
  std::string e = failed_;
  failed_.clear();
  if (!exec("COMMIT") && e.empty()) e = error("cannot commit");
  if (!e.empty()) exec("ROLLBACK");
  return e;
}

void RecordDb::close() {
  if (db_ == nullptr) return;
  commit();
  for (sqlite3_stmt* p : {robot_, heard_, state_, sent_, answered_, report_, missing_, epoch_}) sqlite3_finalize(p);
  robot_ = heard_ = state_ = sent_ = answered_ = report_ = missing_ = epoch_ = nullptr;
  sqlite3_close(db_);
  db_ = nullptr;
}

}  // namespace ev3master
