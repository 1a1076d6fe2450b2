#pragma once
// Reading a result file (report.json, detect's or evaluate's output) in a
// test: a missing or malformed file is a failure that names it, not an
// exception thrown out of the test.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_command.h"

namespace tagsfm::testing {

// The file's JSON; null (after a failure naming the file) when it cannot be
// read or parsed.
inline nlohmann::json ReadJsonFile(const std::filesystem::path& path) {
  nlohmann::json json = nlohmann::json::parse(ReadText(path), nullptr, false);
  if (!json.is_discarded()) return json;
  ADD_FAILURE() << path.string() << " is missing or not JSON";
  return nlohmann::json();
}

}  // namespace tagsfm::testing
