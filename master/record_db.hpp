/// @file record_db.hpp
/// @brief ev3-master's `--db FILE`: what the operator asks about after a mission, kept in SQLite
///        (the system library, WAL): robots, state changes, commands and their answers, every report
///        with its number, drops, epochs. Rows are collected during a loop turn and committed once
///        at its end. docs/record.md gives the schema.
#pragma once

#include <cstdint>
#include <string>

struct sqlite3;
struct sqlite3_stmt;

namespace ev3master {

#ifdef EV3_HAVE_SQLITE
class RecordDb {
 public:
  /// The schema this build writes (PRAGMA user_version); older files are migrated on open.
  static constexpr int kSchema = 3;
  /// PRAGMA application_id of a record: "EV3R".
  static constexpr std::int32_t kApplicationId = 0x45563352;

  RecordDb() = default;
  RecordDb(const RecordDb&) = delete;
  RecordDb& operator=(const RecordDb&) = delete;
  ~RecordDb();

  /// Opens or creates @p path. Refuses, with the reason, a file that is no SQLite database, another
  /// program's database, or one of a newer schema. Returns "" or the error.
  std::string open(const std::string& path);
  bool is_open() const noexcept { return db_ != nullptr; }
  /// A note for the operator after open(): "created", "continued (N reports)", "migrated from ...".
  const std::string& opened() const noexcept { return opened_; }

  // Rows of this loop turn; @p t: the wall clock in ms since 1970.
  /// @p model "" when not known; @p devices: the devices it announced, a JSON array ("" when not known).
  void robot_seen(std::uint16_t id, std::uint16_t announced, const std::string& address, const std::string& model,
                  const std::string& devices, std::int64_t t);
  void robots_heard(std::uint16_t id, std::int64_t t);
  void state(std::uint16_t id, const std::string& state, std::int64_t t);
  /// A command's row (its answer NULL); returns the row's number for command_answered().
  std::int64_t command_sent(std::uint16_t id, const std::string& command, const std::string& args, std::int64_t t);
  void command_answered(std::int64_t row, const std::string& answer, const std::string& reason, std::int64_t t);
  void report(std::uint16_t id, std::uint32_t seq, const std::string& type, const std::string& text, std::int64_t t);
  void reports_missing(std::uint16_t id, std::uint32_t first, std::uint32_t last, const std::string& kind,
                       std::int64_t t);
  void epoch(std::uint32_t epoch, const std::string& role, const std::string& members, std::int64_t t);

  /// Commits the turn's rows (nothing when there are none). Returns "" or the error.
  std::string commit();
  /// Commits what is left and closes the file.
  void close();

 private:
  bool exec(const char* sql);
  std::string error(const std::string& what) const;
  sqlite3_stmt* prepare(const char* sql);
  bool begin();
  void step(sqlite3_stmt* s);

  sqlite3* db_ = nullptr;
  bool in_tx_ = false;
  std::string failed_;  // the first error of this turn
  std::string opened_;
  sqlite3_stmt* robot_ = nullptr;
  sqlite3_stmt* heard_ = nullptr;
  sqlite3_stmt* state_ = nullptr;
  sqlite3_stmt* sent_ = nullptr;
  sqlite3_stmt* answered_ = nullptr;
  sqlite3_stmt* report_ = nullptr;
  sqlite3_stmt* missing_ = nullptr;
  sqlite3_stmt* epoch_ = nullptr;
};
#else
/// Built without SQLite (the armel build): --db is refused, nothing is written.
class RecordDb {
 public:
  std::string open(const std::string&) { return "bad value for --db: this ev3-master is built without SQLite"; }
  bool is_open() const noexcept { return false; }
  const std::string& opened() const noexcept { return opened_; }
  void robot_seen(std::uint16_t, std::uint16_t, const std::string&, const std::string&, const std::string&,
                  std::int64_t) {}
  void robots_heard(std::uint16_t, std::int64_t) {}
  void state(std::uint16_t, const std::string&, std::int64_t) {}
  std::int64_t command_sent(std::uint16_t, const std::string&, const std::string&, std::int64_t) { return 0; }
  void command_answered(std::int64_t, const std::string&, const std::string&, std::int64_t) {}
  void report(std::uint16_t, std::uint32_t, const std::string&, const std::string&, std::int64_t) {}
  void reports_missing(std::uint16_t, std::uint32_t, std::uint32_t, const std::string&, std::int64_t) {}
  void epoch(std::uint32_t, const std::string&, const std::string&, std::int64_t) {}
  std::string commit() { return {}; }
  void close() {}

 private:
  std::string opened_;
};
#endif

}  // namespace ev3master
