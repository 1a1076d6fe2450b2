#pragma once
// Writing result files so that a reader never sees half of one.
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "tagsfm/core/result.h"

namespace tagsfm {

// Writes to `path.tmp`, fsyncs, renames over `path`.
Status WriteFileAtomically(const std::filesystem::path& path, std::string_view contents);
Status WriteFileAtomically(const std::filesystem::path& path, const std::vector<unsigned char>& bytes);

Result<std::string> ReadFileToString(const std::filesystem::path& path);

// Splits one CSV line on commas (no quoting: our files never need it), trims spaces.
std::vector<std::string> SplitCsvLine(std::string_view line);

// Parses a whole string as a number; false on any trailing garbage.
bool ParseDouble(std::string_view text, double* value);
bool ParseInt64(std::string_view text, long long* value);

}  // namespace tagsfm
