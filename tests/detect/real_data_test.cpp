// Decoding, corner order and pixel convention on real images (../shared/data).
// None of these sets has independent sub-pixel truth: the references are
// libapriltag's own raw corners (pixel centres at .5), so with kNone our
// corners must equal them minus half a pixel.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tagsfm/capture/recording.h"
#include "tagsfm/detect/tag_detector.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

namespace fs = std::filesystem;
using testing::SharedDataDir;

struct ReferenceTag {
  TagId id = -1;
  std::array<Eigen::Vector2d, 4> corners;  // libapriltag's convention (centres at .5)
};

cv::Mat LoadGray(const fs::path& file) {
  auto frame = LoadImageFrame(file, 0, 0);
  EXPECT_TRUE(frame.has_value()) << (frame ? "" : frame.error().message);
  return frame ? frame->gray : cv::Mat();
}

std::unique_ptr<TagDetector> RawDetector(const std::string& family, float decimate, bool refine_edges,
                                         int max_hamming = 0) {
  TagDetectorOptions options;
  options.family = family;
  options.quad_decimate = decimate;
  options.refine_edges = refine_edges;
  options.refinement = CornerRefinement::kNone;
  options.min_decision_margin = 0.0;
  options.max_hamming = max_hamming;
  options.threads = 1;
  auto detector = TagDetector::Create(options);
  EXPECT_TRUE(detector.has_value());
  return detector ? std::move(*detector) : nullptr;
}

// Largest corner distance between a detection (OpenCV convention) and a
// reference in libapriltag's convention, shifted by half a pixel.
double MaxCornerGap(const TagDetection& det, const ReferenceTag& ref) {
  double worst = 0.0;
  for (int k = 0; k < 4; ++k) {
    worst = std::max(worst, (det.corners[k] + Eigen::Vector2d(0.5, 0.5) - ref.corners[k]).norm());
  }
  return worst;
}

// Every reference tag must be matched by a detection of the same id (the
// nearest, as an image may hold one id several times); returns the worst gap.
double MatchAll(const std::vector<ReferenceTag>& refs, const DetectionSet& found, const std::string& where) {
  double worst = 0.0;
  for (const ReferenceTag& ref : refs) {
    double best = 1e9;
    for (const TagDetection& det : found.tags) {
      if (det.id == ref.id) best = std::min(best, MaxCornerGap(det, ref));
    }
    EXPECT_LT(best, 1e9) << where << ": tag " << ref.id << " not found";
    if (best < 1e9) worst = std::max(worst, best);
  }
  return worst;
}

// visp benchmark: "corners_tagXX_YY.txt" = blocks of id then 4 lines "u v".
std::vector<ReferenceTag> ReadVispBenchmarkCorners(const fs::path& file) {
  std::ifstream in(file);
  std::vector<ReferenceTag> refs;
  ReferenceTag tag;
  while (in >> tag.id) {
    for (auto& c : tag.corners) in >> c.x() >> c.y();
    if (!in) break;
    refs.push_back(tag);
  }
  return refs;
}

TEST(RealData, VispBenchmarkEveryFamily) {
  TAGSFM_REQUIRE_SHARED_DATA("visp-apriltag/AprilTag/benchmark/640x480");
  const fs::path dir = SharedDataDir() / "visp-apriltag/AprilTag/benchmark/640x480";
  const std::map<std::string, std::string> families{
      {"16_05", "tag16h5"},          {"21_07", "tagCircle21h7"},  {"25_09", "tag25h9"},
      {"36_11", "tag36h11"},         {"41_12", "tagStandard41h12"}, {"48_12", "tagCustom48h12"},
      {"49_12", "tagCircle49h12"},   {"52_13", "tagStandard52h13"}};
  for (const auto& [code, family] : families) {
    const auto refs = ReadVispBenchmarkCorners(dir / ("corners_tag" + code + ".txt"));
    ASSERT_EQ(refs.size(), 5u) << family;
    const cv::Mat image = LoadGray(dir / ("tag" + code + "_640x480.png"));
    // The reference was made at quad_decimate 1 with refine_edges on (its
    // corners match that run within 0.001 px, and no other within 0.08 px).
    auto detector = RawDetector(family, 1.0f, true);
    auto found = detector->Detect(image, 0);
    ASSERT_TRUE(found.has_value()) << family;
    std::set<TagId> ids;
    for (const auto& t : found->tags) ids.insert(t.id);
    EXPECT_EQ(ids.size(), 5u) << family;
    const double worst = MatchAll(refs, *found, family);
    std::printf("%-17s found %zu, worst corner gap to reference %.4f px\n", family.c_str(), found->tags.size(), worst);
    // The same run as the reference's: equal up to float printing, once
    // shifted by half a pixel (unshifted they would be 0.71 px apart).
    EXPECT_LT(worst, 0.01) << family;
  }
}

// visp AprilTag.png: ground_truth_detection.txt = "36h11_id:_N" then 4 lines
// "v u" (row, column).
std::vector<ReferenceTag> ReadVispPhotoCorners(const fs::path& file) {
  std::ifstream in(file);
  std::vector<ReferenceTag> refs;
  std::string label;
  while (in >> label) {
    ReferenceTag tag;
    const auto colon = label.find(":_");
    if (colon == std::string::npos) break;
    tag.id = std::stoi(label.substr(colon + 2));
    for (auto& c : tag.corners) in >> c.y() >> c.x();
    if (!in) break;
    refs.push_back(tag);
  }
  return refs;
}

TEST(RealData, VispPhotoIdsAndCorners) {
  TAGSFM_REQUIRE_SHARED_DATA("visp-apriltag/AprilTag/AprilTag.png");
  const fs::path dir = SharedDataDir() / "visp-apriltag/AprilTag";
  const auto refs = ReadVispPhotoCorners(dir / "ground_truth_detection.txt");
  ASSERT_EQ(refs.size(), 12u);  // ids 8..19
  const cv::Mat image = LoadGray(dir / "AprilTag.png");
  double best_worst = 1e9;
  // Every setting finds the same ids; the reference's own setting (decimate
  // 1, refine_edges on) matches its corners.
  for (bool refine_edges : {false, true}) {
    for (float decimate : {1.0f, 2.0f}) {
      auto found = RawDetector("tag36h11", decimate, refine_edges)->Detect(image, 0);
      ASSERT_TRUE(found.has_value());
      std::set<TagId> ids;
      for (const auto& t : found->tags) ids.insert(t.id);
      std::set<TagId> expected;
      for (const auto& r : refs) expected.insert(r.id);
      EXPECT_EQ(ids, expected) << "decimate " << decimate << " refine_edges " << refine_edges;
      const double worst = MatchAll(refs, *found, "AprilTag.png");
      std::printf("AprilTag.png decimate %.0f refine_edges %d: worst gap %.4f px\n", decimate, refine_edges, worst);
      best_worst = std::min(best_worst, worst);
    }
  }
  // The data README: the reference matches a plain libapriltag 3.3 run
  // within 0.05 px; one of the settings must be that run.
  EXPECT_LT(best_worst, 0.05);
}

// apriltag-testdata: "id, (x y), (x y), (x y), (x y)" per line, made with
// quad_decimate 1, refine_edges off.
std::vector<ReferenceTag> ReadAprilTagTestCorners(const fs::path& file) {
  std::ifstream in(file);
  std::vector<ReferenceTag> refs;
  std::string line;
  while (std::getline(in, line)) {
    for (char& c : line) {
      if (c == ',' || c == '(' || c == ')') c = ' ';
    }
    std::istringstream fields(line);
    ReferenceTag tag;
    if (!(fields >> tag.id)) continue;
    for (auto& c : tag.corners) fields >> c.x() >> c.y();
    if (fields) refs.push_back(tag);
  }
  return refs;
}

TEST(RealData, AprilTagTestDataIdsAndCorners) {
  TAGSFM_REQUIRE_SHARED_DATA("apriltag-testdata/test/data");
  const fs::path dir = SharedDataDir() / "apriltag-testdata/test/data";
  auto detector = RawDetector("tag36h11", 1.0f, false, 2);
  Eigen::Vector2d offset_sum = Eigen::Vector2d::Zero();
  int corners = 0;
  int images = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() != ".jpg") continue;
    ++images;
    auto refs = ReadAprilTagTestCorners(fs::path(entry.path()).replace_extension(".txt"));
    ASSERT_FALSE(refs.empty()) << entry.path();
    auto found = detector->Detect(LoadGray(entry.path()), 0);
    ASSERT_TRUE(found.has_value());
    EXPECT_EQ(found->tags.size(), refs.size()) << entry.path();
    const double worst = MatchAll(refs, *found, entry.path().filename().string());
    std::printf("%s: %zu tags (reference %zu), worst gap %.4f px\n", entry.path().filename().c_str(),
                found->tags.size(), refs.size(), worst);
    // The reference came from libapriltag's own JPEG decoder and a newer
    // version: pixels and corners differ by up to ~0.3 px, at random.
    EXPECT_LT(worst, 0.5) << entry.path();
    for (const ReferenceTag& ref : refs) {
      for (const TagDetection& det : found->tags) {
        if (det.id != ref.id || MaxCornerGap(det, ref) > 0.5) continue;
        for (int k = 0; k < 4; ++k) offset_sum += det.corners[k] + Eigen::Vector2d(0.5, 0.5) - ref.corners[k];
        corners += 4;
      }
    }
  }
  EXPECT_EQ(images, 3);
  // ...but not systematically: the mean offset pins the half-pixel shift.
  ASSERT_GT(corners, 100);
  const Eigen::Vector2d mean = offset_sum / corners;
  std::printf("apriltag-testdata: mean offset after the shift (%+.4f, %+.4f) px over %d corners\n", mean.x(),
              mean.y(), corners);
  EXPECT_LT(mean.norm(), 0.05);
}

// swatbotics mapping: "IMG_xxxx.JPG id id ..." per line. No id that is not
// listed may ever appear, with or without the small-tag pass (which reads
// with margin 0 here too: the most permissive). Recall: the issue asks for
// 100%; measured at quad_decimate 1: 227/236 by libapriltag alone (missed:
// tags of ~2 px modules in IMG_1409, 1415, 1428, 1450, 1451; no libapriltag
// setting tried finds them: see docs/detection.md), 236/236 with the
// small-tag pass (its blur-model reading adds IMG_1409 11, 13 and IMG_1451 7,
// 9 to the 232 of the module-centre reading; 11 only with the correlated
// blur of a diagonal motion), at the default quad_decimate 2: 216/236.
TEST(RealDataSlow, SwatboticsMappingRecall) {
  TAGSFM_REQUIRE_SHARED_DATA("swatbotics-mapping/images/mapping_feb_2014");
  const fs::path dir = SharedDataDir() / "swatbotics-mapping/images/mapping_feb_2014";
  struct Setting {
    bool small_tag_pass;
    double min_margin;
    int min_found;
  };
  for (const Setting setting : {Setting{false, 0.02, 227}, Setting{true, 0.02, 236}, Setting{true, 0.0, 236}}) {
    std::ifstream in(dir / "groundtruth.txt");
    TagDetectorOptions options;
    options.quad_decimate = 1.0f;
    options.small_tag_pass = setting.small_tag_pass;
    options.small_tag_min_margin = setting.min_margin;
    auto detector = TagDetector::Create(options);
    ASSERT_TRUE(detector.has_value());
    std::string line;
    int images = 0, expected_tags = 0, found_tags = 0, extra_tags = 0;
    while (std::getline(in, line)) {
      std::istringstream fields(line);
      std::string name;
      if (!(fields >> name)) continue;
      std::set<TagId> expected;
      for (TagId id; fields >> id;) expected.insert(id);
      auto found = (*detector)->Detect(LoadGray(dir / name), images++);
      ASSERT_TRUE(found.has_value()) << name;
      std::set<TagId> ids;
      for (const auto& t : found->tags) ids.insert(t.id);
      for (TagId id : ids) EXPECT_TRUE(expected.count(id)) << name << ": id " << id << " is not there";
      expected_tags += static_cast<int>(expected.size());
      for (TagId id : ids) (expected.count(id) ? found_tags : extra_tags)++;
      for (TagId id : expected) {
        if (!ids.count(id)) std::printf("  missed %s %d\n", name.c_str(), id);
      }
    }
    std::printf("swatbotics, small_tag_pass %d (margin %.2f): %d images, %d/%d listed tags found, %d extra\n",
                setting.small_tag_pass, setting.min_margin, images, found_tags, expected_tags, extra_tags);
    EXPECT_EQ(images, 72);
    EXPECT_EQ(extra_tags, 0);
    EXPECT_GE(found_tags, setting.min_found);
  }
}

// The small-tag pass on the synth renderer's recordings: every tag it adds
// is in front of the camera and within 1 px (each corner) of its projected
// truth, the first pass's tags are unchanged.
TEST(RealDataSlow, SmallTagPassOnRecordingsAddsNoFalseTag) {
  int added = 0, checked_frames = 0;
  std::vector<double> added_errors;  // px, every corner of every added tag
  for (const std::string name : {"wall_small", "box_small", "box_photos"}) {
    const fs::path dir = testing::RecordingsDir() / name;
    if (!fs::exists(dir / "ground_truth")) continue;
    auto reader = RecordingReader::Open(dir);
    ASSERT_TRUE(reader.has_value()) << name;
    auto targets = ReadTargetsCsv(dir / "ground_truth/targets.csv");
    auto poses = ReadPosesCsv(dir / "ground_truth/poses.csv");
    ASSERT_TRUE(targets.has_value() && poses.has_value() && reader->info().camera) << name;
    const CameraModel& camera = *reader->info().camera;
    for (float decimate : {1.0f, 2.0f}) {
      TagDetectorOptions options;
      options.family = reader->info().targets.family;
      options.quad_decimate = decimate;
      auto plain = TagDetector::Create(options);
      options.small_tag_pass = true;
      options.small_tag_min_margin = 0.0;  // the most permissive reading
      auto with_pass = TagDetector::Create(options);
      ASSERT_TRUE(plain.has_value() && with_pass.has_value());
      for (size_t i = 0; i < reader->entries().size(); ++i) {
        auto frame = reader->LoadFrame(i);
        ASSERT_TRUE(frame.has_value());
        const auto pose = poses->find(frame->index);
        if (pose == poses->end()) continue;
        auto a = (*plain)->Detect(frame->gray, frame->index);
        auto b = (*with_pass)->Detect(frame->gray, frame->index);
        ASSERT_TRUE(a.has_value() && b.has_value());
        ++checked_frames;
        std::map<TagId, decltype(TagDetection::corners)> first;
        for (const auto& t : a->tags) first[t.id] = t.corners;
        for (const auto& t : b->tags) {
          const auto f = first.find(t.id);
          if (f != first.end()) {
            for (int k = 0; k < 4; ++k) EXPECT_EQ(t.corners[k], f->second[k]) << name << " frame " << i;
            continue;
          }
          ++added;
          const auto target = targets->find(t.id);
          ASSERT_TRUE(target != targets->end()) << name << " frame " << i << ": id " << t.id << " is not a target";
          for (int k = 0; k < 4; ++k) {
            const Eigen::Vector3d in_cam = pose->second * target->second[k];
            ASSERT_GT(in_cam.z(), 0.05) << name << " frame " << i << ": id " << t.id << " is behind the camera";
            added_errors.push_back((camera.Project(in_cam) - t.corners[k]).norm());
            EXPECT_LT(added_errors.back(), 1.0)
                << name << " frame " << i << ": id " << t.id << " corner " << k << " at " << t.corners[k].transpose()
                << " truth " << camera.Project(in_cam).transpose() << " decimate " << decimate << " tags " << b->tags.size()
                << " margin " << t.decision_margin;
          }
        }
      }
    }
  }
  std::sort(added_errors.begin(), added_errors.end());
  ASSERT_FALSE(added_errors.empty());
  std::printf("small-tag pass on the recordings: %d frames (x2 decimations), %d tags added, corners to the truth "
              "median %.3f, p95 %.3f, max %.3f px\n",
              checked_frames, added, added_errors[added_errors.size() / 2],
              added_errors[added_errors.size() * 95 / 100], added_errors.back());
  // Measured: 348 tags (60 by the module-centre reading alone), median 0.051 px.
  EXPECT_GE(added, 250);
  EXPECT_LT(added_errors[added_errors.size() / 2], 0.1);
}

// A NumPy .npy file of float64 (little-endian, C order): its shape and values.
struct NpyArray {
  std::vector<size_t> shape;
  std::vector<double> values;
};

std::optional<NpyArray> ReadNpyFloat64(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  char magic[8];
  if (!in.read(magic, 8) || std::string(magic, 6) != "\x93NUMPY") return std::nullopt;
  size_t header_length = 0;
  if (magic[6] == 1) {
    unsigned char len[2];
    in.read(reinterpret_cast<char*>(len), 2);
    header_length = len[0] | (len[1] << 8);
  } else {
    unsigned char len[4];
    in.read(reinterpret_cast<char*>(len), 4);
    header_length = len[0] | (len[1] << 8) | (len[2] << 16) | (static_cast<size_t>(len[3]) << 24);
  }
  std::string header(header_length, ' ');
  if (!in.read(header.data(), static_cast<std::streamsize>(header_length))) return std::nullopt;
  if (header.find("'descr': '<f8'") == std::string::npos || header.find("'fortran_order': False") == std::string::npos) {
    return std::nullopt;
  }
  const auto open = header.find('(', header.find("'shape'"));
  const auto close = header.find(')', open);
  NpyArray array;
  std::string dims = header.substr(open + 1, close - open - 1);
  for (char& c : dims) c = c == ',' ? ' ' : c;
  std::istringstream dim_stream(dims);
  size_t count = 1;
  for (size_t d; dim_stream >> d;) {
    array.shape.push_back(d);
    count *= d;
  }
  array.values.resize(count);
  if (!in.read(reinterpret_cast<char*>(array.values.data()), static_cast<std::streamsize>(count * sizeof(double)))) {
    return std::nullopt;
  }
  return array;
}

TEST(RealDataSlow, VideoSingleTagCorners) {
  TAGSFM_REQUIRE_SHARED_DATA("video-single-tag/corners.npy");
  const fs::path dir = SharedDataDir() / "video-single-tag";
  const auto npy = ReadNpyFloat64(dir / "corners.npy");
  ASSERT_TRUE(npy.has_value());
  ASSERT_EQ(npy->shape, (std::vector<size_t>{93, 4, 2}));
  auto detector = TagDetector::Create(TagDetectorOptions{});
  ASSERT_TRUE(detector.has_value());
  std::vector<double> gaps;
  int found_frames = 0;
  // Their corner k is ours (k + kShift) % 4: their 3D order starts at
  // (-s/2, -s/2), libapriltag's at the bottom-left (-s/2, +s/2 in a y-down
  // tag frame). Found by matching frame 0, then fixed for all frames.
  int shift = -1;
  for (int f = 0; f < 93; ++f) {
    char name[32];
    std::snprintf(name, sizeof(name), "frame%04d.jpg", f);
    auto found = (*detector)->Detect(LoadGray(dir / "frames" / name), f);
    ASSERT_TRUE(found.has_value());
    const TagDetection* tag = nullptr;
    for (const auto& t : found->tags) {
      if (t.id == 12) tag = &t;
    }
    EXPECT_EQ(found->tags.size(), 1u) << name;
    if (tag == nullptr) continue;
    ++found_frames;
    auto theirs = [&](int k) { return Eigen::Vector2d(npy->values[f * 8 + k * 2], npy->values[f * 8 + k * 2 + 1]); };
    if (shift < 0) {
      double best = 1e9;
      for (int s = 0; s < 4; ++s) {
        double sum = 0.0;
        for (int k = 0; k < 4; ++k) sum += (tag->corners[(k + s) % 4] - theirs(k)).norm();
        if (sum < best) best = sum, shift = s;
      }
      std::printf("video-single-tag: their corner k is our corner (k + %d) %% 4\n", shift);
    }
    for (int k = 0; k < 4; ++k) gaps.push_back((tag->corners[(k + shift) % 4] - theirs(k)).norm());
  }
  EXPECT_EQ(found_frames, 93);
  EXPECT_EQ(shift, 0);  // their order is libapriltag's
  std::sort(gaps.begin(), gaps.end());
  const double median = gaps[gaps.size() / 2];
  const double max = gaps.back();
  std::printf("video-single-tag: corner gap to corners.npy median %.3f px, max %.3f px\n", median, max);
  // corners.npy came from another detector (convention and refinement
  // unknown; one of its corners sits ~1 px off ours in most frames, up to
  // 3.2 px): agreement to about a pixel checks decoding and order, a wrong
  // order would give gaps of a tag side (~50 px).
  EXPECT_LT(median, 1.0);
  EXPECT_LT(max, 4.0);
}

// Where there is no tag of the family, the small-tag pass must not make one
// up: the Middlebury object photos (no tags at all) and the swatbotics
// chessboard photos (a few see the room's tag 0, which libapriltag finds:
// the pass must add nothing to what it finds), for each family the pass
// reads, at the most permissive margin. Measured: nothing added.
TEST(RealDataSlow, SmallTagPassFindsNoTagWhereThereIsNone) {
  TAGSFM_REQUIRE_SHARED_DATA("middlebury-ring");
  std::vector<fs::path> images;
  for (const char* dir : {"middlebury-ring/dinoSparseRing", "middlebury-ring/templeSparseRing",
                          "swatbotics-mapping/images/mapping_feb_2014/calibration"}) {
    if (!fs::exists(SharedDataDir() / dir)) continue;
    for (const auto& entry : fs::directory_iterator(SharedDataDir() / dir)) {
      const std::string ext = entry.path().extension().string();
      if (ext == ".png" || ext == ".JPG" || ext == ".jpg") images.push_back(entry.path());
    }
  }
  ASSERT_GE(images.size(), 32u);
  for (const std::string family : {"tag36h11", "tag25h9"}) {
    TagDetectorOptions options;
    options.family = family;
    options.quad_decimate = 1.0f;
    auto plain = TagDetector::Create(options);
    options.small_tag_pass = true;
    options.small_tag_min_margin = 0.0;
    auto with_pass = TagDetector::Create(options);
    ASSERT_TRUE(plain.has_value() && with_pass.has_value()) << family;
    int first_pass = 0, added = 0;
    for (const fs::path& image : images) {
      const cv::Mat gray = LoadGray(image);
      auto a = (*plain)->Detect(gray, 0);
      auto b = (*with_pass)->Detect(gray, 0);
      ASSERT_TRUE(a.has_value() && b.has_value()) << image;
      std::set<TagId> first;
      for (const auto& t : a->tags) first.insert(t.id);
      first_pass += static_cast<int>(first.size());
      for (const auto& t : b->tags) {
        if (first.count(t.id)) continue;
        ++added;
        ADD_FAILURE() << family << ": id " << t.id << " made up in " << image.filename() << " (margin "
                      << t.decision_margin << ")";
      }
    }
    std::printf("%s: %zu photos, %d tags found by libapriltag, %d added by the small-tag pass\n", family.c_str(),
                images.size(), first_pass, added);
  }
}

}  // namespace
}  // namespace tagsfm
