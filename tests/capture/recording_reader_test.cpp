#include "tagsfm/capture/recording.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "recording_test_util.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::TempDir;
using testing::TestImage;
using testing::WriteTextFile;

bool Contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(RecordingYaml, ReadsEveryField) {
  TempDir tmp;
  WriteTextFile(tmp.path() / "recording.yaml", testing::kMinimalYaml);
  auto info = ReadRecordingYaml(tmp.path() / "recording.yaml");
  ASSERT_TRUE(info) << info.error().message;
  ASSERT_TRUE(info->camera.has_value());
  EXPECT_EQ(info->camera->width, 64);
  EXPECT_DOUBLE_EQ(info->camera->cy, 24.0);
  EXPECT_EQ(info->camera->distortion.size(), 5u);
  EXPECT_EQ(info->targets.family, "tag36h11");
  EXPECT_DOUBLE_EQ(info->targets.SizeOf(3), 0.04);
  EXPECT_DOUBLE_EQ(info->targets.SizeOf(4), 0.08);
}

TEST(RecordingYaml, WriteThenReadGivesTheSameInfo) {
  TempDir tmp;
  RecordingInfo info;
  CameraModel camera;
  camera.width = 1280;
  camera.height = 720;
  camera.fx = 1000.125;
  camera.fy = 999.5;
  camera.cx = 640.25;
  camera.cy = 359.75;
  camera.distortion = {-0.1, 0.01, 0.001, 0.002};
  camera.kind = CameraModel::Kind::kFisheye;
  info.camera = camera;
  info.targets.family = "tagStandard41h12";
  info.targets.size_m = 0.0625;
  info.targets.size_by_id = {{7, 0.03}};
  info.targets.map = "targets.csv";
  WriteTextFile(tmp.path() / "recording.yaml", RecordingYamlText(info));
  auto read = ReadRecordingYaml(tmp.path() / "recording.yaml");
  ASSERT_TRUE(read) << read.error().message;
  EXPECT_EQ(read->camera->kind, CameraModel::Kind::kFisheye);
  EXPECT_EQ(read->camera->fx, camera.fx);
  EXPECT_EQ(read->camera->distortion, camera.distortion);
  EXPECT_EQ(read->targets.family, info.targets.family);
  EXPECT_EQ(read->targets.size_by_id, info.targets.size_by_id);
  EXPECT_EQ(read->targets.map, "targets.csv");
}

TEST(RecordingYaml, CameraBlockIsOptional) {
  TempDir tmp;
  WriteTextFile(tmp.path() / "recording.yaml",
                "format: tagsfm-recording/1\ntargets:\n  family: tag25h9\n  size_m: 0.1\n");
  auto info = ReadRecordingYaml(tmp.path() / "recording.yaml");
  ASSERT_TRUE(info) << info.error().message;
  EXPECT_FALSE(info->camera.has_value());
}

struct BadYamlCase {
  std::string yaml;
  std::string must_mention;
};

class RecordingYamlErrors : public ::testing::TestWithParam<BadYamlCase> {};

TEST_P(RecordingYamlErrors, NameFileAndField) {
  TempDir tmp;
  WriteTextFile(tmp.path() / "recording.yaml", GetParam().yaml);
  auto info = ReadRecordingYaml(tmp.path() / "recording.yaml");
  ASSERT_FALSE(info);
  const std::string& message = info.error().message;
  EXPECT_TRUE(Contains(message, "recording.yaml")) << message;
  EXPECT_TRUE(Contains(message, GetParam().must_mention)) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << "one line: " << message;
}

INSTANTIATE_TEST_SUITE_P(
    Cases, RecordingYamlErrors,
    ::testing::Values(
        BadYamlCase{"targets:\n  family: tag36h11\n  size_m: 0.08\n", "format"},
        BadYamlCase{"format: tagsfm-recording/2\ntargets:\n  family: tag36h11\n  size_m: 0.08\n", "format"},
        BadYamlCase{"format: tagsfm-recording/1\n", "targets"},
        BadYamlCase{"format: tagsfm-recording/1\ntargets:\n  family: tag99h99\n  size_m: 0.08\n", "tag99h99"},
        BadYamlCase{"format: tagsfm-recording/1\ntargets:\n  family: tag36h11\n  size_m: big\n", "size_m"},
        BadYamlCase{"format: tagsfm-recording/1\ntargets:\n  family: tag36h11\n  size_m: -1\n", "size_m"},
        BadYamlCase{"format: tagsfm-recording/1\ncamera:\n  width: 640\n  height: 480\n  fx: 500\n  cx: 320\n"
                    "  cy: 240\ntargets:\n  family: tag36h11\n  size_m: 0.08\n",
                    "camera.fy"},
        BadYamlCase{"format: tagsfm-recording/1\ncamera:\n  width: 640\n  height: 480\n  fx: 500\n  fy: 500\n"
                    "  cx: 320\n  cy: 240\n  distortion: [1, 2, 3]\ntargets:\n  family: tag36h11\n  size_m: 0.08\n",
                    "camera.distortion"},
        BadYamlCase{"format: tagsfm-recording/1\ncamera:\n  width: wide\n  height: 480\n  fx: 500\n  fy: 500\n"
                    "  cx: 320\n  cy: 240\ntargets:\n  family: tag36h11\n  size_m: 0.08\n",
                    "camera.width"},
        BadYamlCase{"format: [unclosed\n", "YAML"}));

class RecordingReaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::filesystem::create_directories(tmp_.path() / "frames");
    WriteTextFile(tmp_.path() / "recording.yaml", testing::kMinimalYaml);
  }
  const std::filesystem::path& dir() const { return tmp_.path(); }
  TempDir tmp_;
};

TEST_F(RecordingReaderTest, ReadsEveryImageKindWithRelativeAndAbsolutePaths) {
  const cv::Mat grey8 = TestImage(1, CV_8UC1), grey16 = TestImage(2, CV_16UC1), colour8 = TestImage(3, CV_8UC3),
                colour16 = TestImage(4, CV_16UC3);
  ASSERT_TRUE(cv::imwrite((dir() / "frames/a.png").string(), grey8));
  ASSERT_TRUE(cv::imwrite((dir() / "frames/b.png").string(), grey16));
  ASSERT_TRUE(cv::imwrite((dir() / "frames/c.png").string(), colour8));
  ASSERT_TRUE(cv::imwrite((dir() / "frames/d.png").string(), colour16));
  ASSERT_TRUE(cv::imwrite((dir() / "frames/e.pgm").string(), grey8));
  ASSERT_TRUE(cv::imwrite((dir() / "frames/f.jpg").string(), colour8));
  WriteTextFile(dir() / "frames.csv", "frame,timestamp_ns,file,exposure_us\n0,0,frames/a.png,100\n1,33,frames/b.png,100\n"
                                      "2,66,frames/c.png,100\n3,99,frames/d.png,100\n4,132,frames/e.pgm,100\n5,165," +
                                          (dir() / "frames/f.jpg").string() + ",100\n");
  auto reader = RecordingReader::Open(dir());
  ASSERT_TRUE(reader) << reader.error().message;
  ASSERT_EQ(reader->entries().size(), 6u);
  for (size_t i = 0; i < 6; ++i) {
    auto frame = reader->LoadFrame(i);
    ASSERT_TRUE(frame) << frame.error().message;
    EXPECT_EQ(frame->index, static_cast<FrameId>(i));
    EXPECT_EQ(frame->timestamp_ns, static_cast<std::int64_t>(i) * 33);
    EXPECT_EQ(frame->gray.type(), CV_8UC1);
    EXPECT_EQ(frame->gray.size(), cv::Size(64, 48));
  }
  // Lossless kinds keep their pixels exactly; 16-bit is scaled 1/257 to 8 bit.
  EXPECT_EQ(cv::norm(reader->LoadFrame(0)->gray, grey8, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(reader->LoadFrame(1)->gray, TestImage(2, CV_8UC1), cv::NORM_INF), 0);
  EXPECT_EQ(reader->LoadFrame(1)->image.depth(), CV_16U);
  EXPECT_EQ(reader->LoadFrame(2)->image.channels(), 3);
  EXPECT_EQ(cv::norm(reader->LoadFrame(4)->gray, grey8, cv::NORM_INF), 0);
}

TEST_F(RecordingReaderTest, BadFramesAreErrorsNamingTheFileAndLineButDoNotStopTheRest) {
  ASSERT_TRUE(cv::imwrite((dir() / "frames/good.png").string(), TestImage(1)));
  std::vector<uchar> png, jpg;
  cv::imencode(".png", TestImage(2), png);
  cv::imencode(".jpg", TestImage(3, CV_8UC3), jpg);
  WriteTextFile(dir() / "frames/truncated.png", std::string(png.begin(), png.begin() + png.size() / 2));
  WriteTextFile(dir() / "frames/truncated.jpg", std::string(jpg.begin(), jpg.begin() + jpg.size() * 2 / 3));
  WriteTextFile(dir() / "frames/empty.png", "");
  WriteTextFile(dir() / "frames/garbage.png", "this is not an image at all");
  WriteTextFile(dir() / "frames.csv",
                "frame,timestamp_ns,file\n0,0,frames/good.png\n1,1,frames/missing.png\n2,2,frames/truncated.png\n"
                "3,3,frames/truncated.jpg\n4,4,frames/empty.png\n5,5,frames/garbage.png\n6,6,frames/good.png\n");
  auto reader = RecordingReader::Open(dir());
  ASSERT_TRUE(reader) << reader.error().message;
  ASSERT_EQ(reader->entries().size(), 7u);
  EXPECT_TRUE(reader->LoadFrame(0));
  EXPECT_TRUE(reader->LoadFrame(6));
  const std::vector<std::pair<size_t, std::string>> bad{
      {1, "missing.png"}, {2, "truncated.png"}, {3, "truncated.jpg"}, {4, "empty.png"}, {5, "garbage.png"}};
  for (const auto& [i, file] : bad) {
    auto frame = reader->LoadFrame(i);
    ASSERT_FALSE(frame) << file;
    const std::string& message = frame.error().message;
    EXPECT_TRUE(Contains(message, file)) << message;
    EXPECT_TRUE(Contains(message, "frames.csv:" + std::to_string(i + 2))) << message;
    EXPECT_TRUE(Contains(message, "frame " + std::to_string(i))) << message;
  }
}

TEST_F(RecordingReaderTest, FramesCsvErrorsNameTheLine) {
  WriteTextFile(dir() / "frames.csv", "frame,timestamp_ns,file\n0,0,frames/a.png\nx,1,frames/b.png\n");
  auto reader = RecordingReader::Open(dir());
  ASSERT_FALSE(reader);
  EXPECT_TRUE(Contains(reader.error().message, "frames.csv:3")) << reader.error().message;
  EXPECT_TRUE(Contains(reader.error().message, "'frame'")) << reader.error().message;

  WriteTextFile(dir() / "frames.csv", "index,time,path\n");
  reader = RecordingReader::Open(dir());
  ASSERT_FALSE(reader);
  EXPECT_TRUE(Contains(reader.error().message, "frames.csv:1")) << reader.error().message;

  std::filesystem::remove(dir() / "frames.csv");
  reader = RecordingReader::Open(dir());
  ASSERT_FALSE(reader);
  EXPECT_TRUE(Contains(reader.error().message, "frames.csv")) << reader.error().message;

  EXPECT_FALSE(RecordingReader::Open(dir() / "nope"));
}

TEST_F(RecordingReaderTest, APartialLastRowFromACrashIsSkippedWithAWarning) {
  ASSERT_TRUE(cv::imwrite((dir() / "frames/a.png").string(), TestImage(1)));
  WriteTextFile(dir() / "frames.csv", "frame,timestamp_ns,file\n0,0,frames/a.png\n1,3");
  auto reader = RecordingReader::Open(dir());
  ASSERT_TRUE(reader) << reader.error().message;
  EXPECT_EQ(reader->entries().size(), 1u);
  ASSERT_EQ(reader->warnings().size(), 1u);
  EXPECT_TRUE(Contains(reader->warnings()[0], "frames.csv:3")) << reader->warnings()[0];
}

TEST_F(RecordingReaderTest, LoadsTheNamedTargetMap) {
  WriteTextFile(dir() / "recording.yaml", std::string(testing::kMinimalYaml) + "  map: targets.csv\n");
  WriteTextFile(dir() / "frames.csv", "frame,timestamp_ns,file\n");
  WriteTextFile(dir() / "targets.csv", "tag_id,corner,x,y,z\n5,0,0,0,0\n5,1,1,0,0\n5,2,1,1,0\n5,3,0,1,0\n");
  auto reader = RecordingReader::Open(dir());
  ASSERT_TRUE(reader) << reader.error().message;
  auto map = reader->LoadTargetMap();
  ASSERT_TRUE(map) << map.error().message;
  ASSERT_TRUE(map->has_value());
  EXPECT_EQ((**map).at(5)[2], Eigen::Vector3d(1, 1, 0));
}

}  // namespace
}  // namespace tagsfm
