#pragma once
// Thin RAII over the SQLite C API for the results store: a connection, cached
// prepared statements and transactions. Every failure throws StoreError
// "<db path>: <operation>: <sqlite message>".

#include "calib/results/store.h"

#include <sqlite3.h>

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>

namespace calib::sqlite {

class Db;

/// A prepared statement borrowed from the Db's cache. Bind parameters are
/// 1-based, columns 0-based (SQLite's convention). On destruction the
/// statement is reset and its bindings cleared, ready for the next user.
class Statement {
 public:
  Statement(Db& db, sqlite3_stmt* stmt, std::string operation)
      : db_(&db), stmt_(stmt), operation_(std::move(operation)) {}
  ~Statement();
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& Bind(int index, int64_t value);
  Statement& Bind(int index, int value) { return Bind(index, static_cast<int64_t>(value)); }
  /// NaN is stored as NULL.
  Statement& Bind(int index, double value);
  Statement& Bind(int index, std::string_view text);
  Statement& Bind(int index, const char* text) { return Bind(index, std::string_view(text)); }
  Statement& Bind(int index, const std::string& text) { return Bind(index, std::string_view(text)); }
  Statement& BindBlob(int index, std::string_view bytes);
  Statement& BindNull(int index);

  /// True with a row to read, false when done. Throws StoreError otherwise.
  bool Step();
  /// Steps to completion (statements without rows).
  void Run();

  bool IsNull(int column) const;
  int64_t Int(int column) const;
  /// NULL reads as NaN.
  double Double(int column) const;
  std::string Text(int column) const;
  std::string Blob(int column) const;
  /// The extended result code of the last failed Step (0 if none).
  int last_error() const { return last_error_; }

 private:
  Db* db_;
  sqlite3_stmt* stmt_;
  std::string operation_;
  int last_error_ = 0;
};

class Db {
 public:
  /// Opens the database; read_only opens without the create flag too.
  Db(const std::filesystem::path& path, bool read_only, int busy_timeout_ms);
  ~Db();
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;

  /// The cached statement for `sql`, prepared on first use. `operation`
  /// names what it does in error messages ("record evaluations").
  Statement Prepare(const std::string& sql, std::string operation);
  /// Runs SQL without results (schema, pragmas).
  void Exec(const std::string& sql, const std::string& operation);
  /// The first column of the first row of `sql` as text ("" if none).
  std::string QueryText(const std::string& sql, const std::string& operation);
  int64_t Changes() const;

  [[noreturn]] void Fail(const std::string& operation, int code) const;
  const std::filesystem::path& path() const { return path_; }
  sqlite3* handle() const { return db_; }

 private:
  std::filesystem::path path_;
  sqlite3* db_ = nullptr;
  std::map<std::string, sqlite3_stmt*> cache_;
};

/// BEGIN IMMEDIATE on construction (the write lock up front, so a busy
/// database waits here rather than failing half-way); ROLLBACK on
/// destruction unless Commit() was called.
class Transaction {
 public:
  Transaction(Db& db, std::string operation);
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  void Commit();

 private:
  Db& db_;
  std::string operation_;
  bool done_ = false;
};

}  // namespace calib::sqlite
