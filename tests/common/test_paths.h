#pragma once
// Where tests find data, and a scratch folder that cleans itself up.
#include <unistd.h>

#include <filesystem>
#include <random>
#include <string>

#include <gtest/gtest.h>

namespace tagsfm::testing {

inline std::filesystem::path SharedDataDir() { return TAGSFM_SHARED_DATA_DIR; }
inline std::filesystem::path RecordingsDir() { return TAGSFM_RECORDINGS_DIR; }
inline std::filesystem::path TagsfmExe() { return TAGSFM_EXE; }

// Skips the calling test, with a message, when ../shared/data/<sub> is absent.
#define TAGSFM_REQUIRE_SHARED_DATA(sub)                                                        \
  do {                                                                                         \
    if (!std::filesystem::exists(::tagsfm::testing::SharedDataDir() / (sub))) {                \
      GTEST_SKIP() << "public test data not found at "                                         \
                   << (::tagsfm::testing::SharedDataDir() / (sub)).string()                    \
                   << " (the ../shared/data folder beside the project); skipping";             \
    }                                                                                          \
  } while (0)

class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() /
            ("tagsfm_test_" + std::to_string(::getpid()) + "_" + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace tagsfm::testing
