#pragma once
// Editing a results store behind its back (to corrupt checkpoints).

#include <filesystem>
#include <string>

namespace calib::testing {

/// Runs `sql` on the SQLite database at `db`; a failure fails the test.
void RawSql(const std::filesystem::path& db, const std::string& sql);

}  // namespace calib::testing
