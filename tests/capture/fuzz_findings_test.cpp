// Inputs the fuzzers (fuzz/) found to crash the recording's readers, kept
// as regression tests: each must now be a one-line error naming the file,
// or read as the contract says.
#include <fstream>

#include <gtest/gtest.h>

#include "tagsfm/capture/capture_settings.h"
#include "tagsfm/capture/recording.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::TempDir;

void WriteFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

const char kValidYaml[] = "format: tagsfm-recording/1\ntargets:\n  family: tag36h11\n  size_m: 0.05\n";

TEST(FuzzFindings, RecordingYamlWithAScalarCameraBlockIsAnError) {
  // recording_yaml_fuzz: `camera:` holding a scalar made yaml-cpp throw
  // BadSubscript out of ReadYamlField (the process aborted).
  TempDir tmp;
  const auto yaml = tmp.path() / "recording.yaml";
  WriteFile(yaml, "format: tagsfm-recording/1\ncamera: 5\ntargets:\n  family: tag36h11\n  size_m: 0.05\n");
  auto info = ReadRecordingYaml(yaml);
  ASSERT_FALSE(info.has_value());
  EXPECT_NE(info.error().message.find("camera.width"), std::string::npos) << info.error().message;
  EXPECT_EQ(info.error().message.find('\n'), std::string::npos) << info.error().message;
  // The fuzzer's own input: the camera block's keys cut into a scalar.
  WriteFile(yaml, "format: tagsfm-recording/1\ncameformat: tagsfm-recording/1\ncamera:\n heig");
  EXPECT_FALSE(ReadRecordingYaml(yaml).has_value());
  // A scalar targets block, and a scalar in the daemon's config reader.
  WriteFile(yaml, "format: tagsfm-recording/1\ntargets: tag36h11\n");
  EXPECT_FALSE(ReadRecordingYaml(yaml).has_value());
  WriteFile(yaml, "camera: fisheye\ntargets:\n  family: tag36h11\n  size_m: 0.05\n");
  EXPECT_FALSE(ReadCameraAndTargets(yaml).has_value());
}

TEST(FuzzFindings, FramesCsvWithABlankFirstLineReadsTheHeaderAfterIt) {
  // frames_csv_fuzz: a blank first line made the reader take the header
  // for a data row and index its fields at -1 (out of bounds).
  TempDir tmp;
  WriteFile(tmp.path() / "recording.yaml", kValidYaml);
  WriteFile(tmp.path() / "frames.csv", "\n\nframe,timestamp_ns,file\n0,0,frames/000000.png\n");
  auto reader = RecordingReader::Open(tmp.path());
  ASSERT_TRUE(reader.has_value()) << reader.error().message;
  ASSERT_EQ(reader->entries().size(), 1u);
  EXPECT_EQ(reader->entries()[0].file, tmp.path() / "frames" / "000000.png");
  // The fuzzer's own input: no header at all after the blank line.
  const char fuzzed[] = "\n\0\0\0frame\3\3\3\3tag36h10tamp_nes/0000ra0";
  WriteFile(tmp.path() / "frames.csv", std::string(fuzzed, sizeof fuzzed - 1));
  auto bad = RecordingReader::Open(tmp.path());
  ASSERT_FALSE(bad.has_value());
  EXPECT_NE(bad.error().message.find("frames.csv:2: header must have the columns"), std::string::npos)
      << bad.error().message;
}

}  // namespace
}  // namespace tagsfm
