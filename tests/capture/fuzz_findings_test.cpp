// Inputs the fuzzers (fuzz/) found to crash the recording's readers, kept
// as regression tests: each must now be a one-line error naming the file,
// or read as the contract says.
#include <cctype>
#include <fstream>

#include <opencv2/imgcodecs.hpp>

#include <gtest/gtest.h>

#include "tagsfm/capture/capture_settings.h"
#include "tagsfm/capture/image_header.h"
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

TEST(FuzzFindings, AnImageWhoseHeaderClaimsAGigapixelIsRefusedBeforeDecoding) {
  // image_decode_fuzz: a 44-byte JPEG whose frame header claims 65361 x
  // 16207 pixels made OpenCV allocate 3.2 GB for it (its own limit is
  // 1 Gpx); on a rig that is the out-of-memory killer. The size is now read
  // from the header first.
  const unsigned char jpeg[] = {0xff, 0xd8, 0xff, 0xe0, 0x00, 0x01, 0x20, 0x28, 0xff, 0xc0, 0x00, 0x11, 0x08, 0x3f, 0x4f,
                                0xff, 0x51, 0x03, 0x01, 0x22, 0x20, 0x02, 0x11, 0x01, 0x03, 0x11, 0xf5, 0xf6, 0xff, 0xda,
                                0x00, 0x0c, 0x03, 0x01, 0x00, 0x02, 0x11, 0x03, 0x11, 0x00, 0xff, 0x00, 0x34, 0x01};
  TempDir tmp;
  WriteFile(tmp.path() / "huge.jpg", std::string(reinterpret_cast<const char*>(jpeg), sizeof jpeg));
  auto frame = LoadImageFrame(tmp.path() / "huge.jpg", 7, 0);
  ASSERT_FALSE(frame.has_value());
  EXPECT_EQ(frame.error().message, (tmp.path() / "huge.jpg").string() +
                                       " (frame 7): its header claims 65361x16207 pixels, more than a frame can have "
                                       "(corrupt?)");
  // The same for a PNG whose IHDR claims 100000 x 100000.
  const char png[] = "\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR\0\x01\x86\xa0\0\x01\x86\xa0\x08\0\0\0\0";
  WriteFile(tmp.path() / "huge.png", std::string(png, sizeof png - 1));
  auto png_frame = LoadImageFrame(tmp.path() / "huge.png", 0, 0);
  ASSERT_FALSE(png_frame.has_value());
  EXPECT_NE(png_frame.error().message.find("claims 100000x100000 pixels"), std::string::npos) << png_frame.error().message;
  // The fuzzer's second input: a PNG whose IHDR claims 4283432959 x
  // 4294967295, whose product overflowed the 64-bit pixel count (UBSan).
  const char sides[] = "\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR\xff\x4f\xff\xff\xff\xff\xff\xff\x08\0\0\0\0";
  WriteFile(tmp.path() / "sides.png", std::string(sides, sizeof sides - 1));
  auto sides_frame = LoadImageFrame(tmp.path() / "sides.png", 0, 0);
  ASSERT_FALSE(sides_frame.has_value());
  EXPECT_NE(sides_frame.error().message.find("claims 4283432959x4294967295 pixels"), std::string::npos)
      << sides_frame.error().message;
}

TEST(FuzzFindings, APpmWhoseWidthEndsInAHashIsSizedAsOpenCvReadsIt) {
  // image_decode_fuzz (2026-12-07): "P6\n599999#1269\n9(99". The header
  // check took '#' for a comment and the height for 9 (5.4 Mpx, allowed);
  // OpenCV's PxM decoder consumes the byte that ends a number, reads the
  // height 1269 and allocated 2.28 GB. The check now reads as OpenCV does.
  TempDir tmp;
  WriteFile(tmp.path() / "frame.ppm", "P6\n599999#1269\n9(99");
  auto frame = LoadImageFrame(tmp.path() / "frame.ppm", 4, 0);
  ASSERT_FALSE(frame.has_value());
  EXPECT_NE(frame.error().message.find("claims 599999x1269 pixels"), std::string::npos) << frame.error().message;
  // A comment after white space is still a comment, and one ended by '\r'.
  WriteFile(tmp.path() / "frame.pgm", "P5 #c\r2 # a comment\n1 255\n" + std::string("\x10\x20", 2));
  auto pgm = LoadImageFrame(tmp.path() / "frame.pgm", 0, 0);
  ASSERT_TRUE(pgm.has_value()) << pgm.error().message;
  EXPECT_EQ(pgm->gray.cols, 2);
  EXPECT_EQ(pgm->gray.at<std::uint8_t>(0, 1), 0x20);
}

TEST(FuzzFindings, AJpegLookalikeWithADicomSignatureIsRefusedNotDecoded) {
  // image_decode_fuzz (2026-12-05): FF D8 00 (not a JPEG to OpenCV, which
  // wants FF D8 FF) with "DICM" at byte 128. The header walk took it for a
  // JPEG, imdecode gave it to GDCM's DICOM reader, whose assert aborted the
  // process. The magic bytes are now the ones OpenCV's own PNG, JPEG and
  // PxM decoders check, so what passes them reaches those decoders only.
  static const unsigned char kInput[] = {
      0xff, 0xd8, 0x00, 0x00, 0x04, 0x05, 0x06, 0x87, 0x08, 0xac, 0x09, 0x0a, 0x0b, 0xff, 0xc4, 0x00,
      0x11, 0x00, 0x02, 0xb5, 0x01, 0xf3, 0xf4, 0xf5, 0xf6, 0x00, 0x43, 0x01, 0x07, 0x07, 0x07, 0x0a,
      0x08, 0x0a, 0x13, 0x0a, 0x0a, 0x13, 0x28, 0x1a, 0x16, 0x1a, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28,
      0x28, 0x28, 0x3d, 0x28, 0x28, 0x28, 0x30, 0x28, 0x28, 0x28, 0x28, 0x2d, 0x28, 0x28, 0x28, 0x28,
      0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28,
      0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x28, 0x60, 0x6f, 0xee, 0xbb, 0xa7,
      0xfc, 0x7f, 0x00, 0x00, 0x28, 0xff, 0xc0, 0x00, 0x11, 0x08, 0x00, 0x12, 0x00, 0x18, 0x03, 0x01,
      0x22, 0x01, 0x0a, 0x11, 0x01, 0x03, 0x11, 0x01, 0xd5, 0xe6, 0x3a, 0x2f, 0x2f, 0xe7, 0xe8, 0xff,
      0x44, 0x49, 0x43, 0x4d, 0x11,
  };
  TempDir tmp;
  WriteFile(tmp.path() / "frame.jpg", std::string(reinterpret_cast<const char*>(kInput), sizeof kInput));
  auto frame = LoadImageFrame(tmp.path() / "frame.jpg", 3, 0);
  ASSERT_FALSE(frame.has_value());
  EXPECT_NE(frame.error().message.find("frame.jpg (frame 3)"), std::string::npos) << frame.error().message;
  EXPECT_NE(frame.error().message.find("not a PNG, JPEG or PGM/PPM"), std::string::npos) << frame.error().message;
  // A portable anymap's magic is followed by white space, as OpenCV checks.
  WriteFile(tmp.path() / "frame.pgm", "P51 1 255\n" + std::string(1, '\0'));
  EXPECT_FALSE(LoadImageFrame(tmp.path() / "frame.pgm", 0, 0).has_value());
  WriteFile(tmp.path() / "frame.pgm", "P5 1 1 255\n" + std::string(1, '\x80'));
  auto pgm = LoadImageFrame(tmp.path() / "frame.pgm", 0, 0);
  ASSERT_TRUE(pgm.has_value()) << pgm.error().message;
  EXPECT_EQ(pgm->gray.at<std::uint8_t>(0, 0), 0x80);
}

TEST(ImageHeader, TheSizeReadFromTheHeaderIsTheDecodedSizeOnEveryRealPhoto) {
  // The header walk must never refuse a real file: every PNG and JPEG of
  // ../shared/data (phone photos with EXIF, Middlebury, AprilTag test sets,
  // video frames) claims in its header the size it decodes to.
  const std::filesystem::path data = testing::SharedDataDir();
  if (!std::filesystem::exists(data)) GTEST_SKIP() << data << " is absent";
  int checked = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(data)) {
    std::string ext = entry.path().extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".png" && ext != ".jpg" && ext != ".jpeg") continue;
    std::ifstream in(entry.path(), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto claimed = EncodedImageSize(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
    const cv::Mat decoded = cv::imread(entry.path().string(), cv::IMREAD_UNCHANGED);
    if (decoded.empty()) continue;
    ASSERT_TRUE(claimed.has_value()) << entry.path();
    EXPECT_EQ(claimed->width, decoded.cols) << entry.path();
    EXPECT_EQ(claimed->height, decoded.rows) << entry.path();
    ++checked;
  }
  EXPECT_GT(checked, 100) << "images checked";
}

}  // namespace
}  // namespace tagsfm
