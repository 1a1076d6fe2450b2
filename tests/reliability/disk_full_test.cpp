// Recording onto a full or read-only filesystem: `record` stops with a
// one-line message and leaves the recording readable up to the last frame
// it wrote whole. The filesystems are small tmpfs mounts, made by the test
// when it runs as root (skipped otherwise).
#include <sys/mount.h>

#include <gtest/gtest.h>

#include "child_process.h"
#include "run_command.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::ReadText;
using testing::TempDir;
namespace fs = std::filesystem;

// A tmpfs of `size` mounted on a fresh folder for the test's lifetime.
class TmpfsMount {
 public:
  TmpfsMount(const fs::path& dir, const std::string& size) : dir_(dir) {
    fs::create_directories(dir_);
    mounted_ = ::getuid() == 0 && ::mount("tmpfs", dir_.c_str(), "tmpfs", 0, ("size=" + size).c_str()) == 0;
  }
  ~TmpfsMount() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  bool MakeReadOnly() { return ::mount("tmpfs", dir_.c_str(), "tmpfs", MS_REMOUNT | MS_RDONLY, nullptr) == 0; }

 private:
  fs::path dir_;
  bool mounted_ = false;
};

// The lines of `log` that spdlog marked as errors.
std::vector<std::string> ErrorLines(const std::string& log) {
  std::vector<std::string> lines;
  std::istringstream in(log);
  for (std::string line; std::getline(in, line);) {
    if (line.find("error") != std::string::npos) lines.push_back(line);
  }
  return lines;
}

class DiskFull : public ::testing::Test {
 protected:
  void SetUp() override {
    box_ = testing::RecordingsDir() / "box_small";
    if (!fs::exists(box_)) GTEST_SKIP() << "recordings/box_small is missing";
    if (::getuid() != 0) GTEST_SKIP() << "mounting a small tmpfs needs root; skipping";
    testing::WriteLoopedRecording(box_, 3, tmp_.path() / "source");
  }
  std::string Record(const fs::path& out, const fs::path& log) {
    const int code = testing::RunCommand(testing::TagsfmExe().string() + " record --source file:" +
                                             (tmp_.path() / "source").string() + "?rate=max --out " + out.string(),
                                         log);
    EXPECT_EQ(code, 1) << "record should stop with exit code 1:\n" << ReadText(log);
    return ReadText(log);
  }

  fs::path box_;
  TempDir tmp_;
};

TEST_F(DiskFull, RecordingOntoAFullDiskStopsWithOneLineAndKeepsTheFramesWritten) {
  // 2 MB: the header and about ten 200 kB frames fit, of the 60 offered.
  TmpfsMount disk(tmp_.path() / "disk", "2m");
  if (!disk.mounted()) GTEST_SKIP() << "mount -t tmpfs failed (no CAP_SYS_ADMIN?); skipping";
  const fs::path rec = tmp_.path() / "disk" / "rec";
  const std::string log = Record(rec, tmp_.path() / "full.log");
  const auto errors = ErrorLines(log);
  ASSERT_EQ(errors.size(), 1u) << log;
  EXPECT_NE(errors[0].find("No space left"), std::string::npos) << errors[0];

  auto source = RecordingReader::Open(tmp_.path() / "source");
  auto recorded = RecordingReader::Open(rec);
  ASSERT_TRUE(source && recorded) << (recorded ? "" : recorded.error().message);
  ASSERT_GE(recorded->entries().size(), 2u);
  ASSERT_LT(recorded->entries().size(), source->entries().size());
  for (size_t i = 0; i < recorded->entries().size(); ++i) {
    auto got = recorded->LoadFrame(i);
    auto want = source->LoadFrame(i);
    ASSERT_TRUE(got.has_value()) << got.error().message;
    ASSERT_TRUE(want.has_value());
    EXPECT_EQ(cv::norm(got->image, want->image, cv::NORM_INF), 0) << "frame " << i;
  }
  // The truncated recording replays (results beside the full disk).
  const fs::path out = tmp_.path() / "out";
  EXPECT_EQ(testing::RunCommand(testing::TagsfmExe().string() + " replay " + rec.string() + " --out " + out.string() +
                                    " --no-features",
                                tmp_.path() / "replay.log"),
            0)
      << ReadText(tmp_.path() / "replay.log");
}

TEST_F(DiskFull, RecordingIntoAReadOnlyFolderIsAOneLineError) {
  TmpfsMount disk(tmp_.path() / "ro", "1m");
  if (!disk.mounted()) GTEST_SKIP() << "mount -t tmpfs failed (no CAP_SYS_ADMIN?); skipping";
  fs::create_directories(tmp_.path() / "ro" / "captures");
  ASSERT_TRUE(disk.MakeReadOnly());
  const std::string log = Record(tmp_.path() / "ro" / "captures" / "rec", tmp_.path() / "ro.log");
  const auto errors = ErrorLines(log);
  ASSERT_EQ(errors.size(), 1u) << log;
  EXPECT_NE(errors[0].find("Read-only file system"), std::string::npos) << errors[0];
  EXPECT_NE(errors[0].find("rec"), std::string::npos) << "the message should name the folder: " << errors[0];
}

}  // namespace
}  // namespace tagsfm
