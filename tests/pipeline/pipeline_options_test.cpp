// The pipeline: block: values reach the structs, and every wrong value is a
// one-line error naming the file and the field.
#include <fstream>

#include <gtest/gtest.h>

#include "tagsfm/pipeline/pipeline_options.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

class PipelineOptionsFile : public ::testing::Test {
 protected:
  Result<PipelineOptions> Read(const std::string& yaml) {
    std::ofstream(file_) << yaml;
    return ReadPipelineOptionsFile(file_);
  }
  std::string ErrorOf(const std::string& yaml) {
    auto options = Read(yaml);
    return options ? std::string("(no error)") : options.error().message;
  }
  testing::TempDir tmp_;
  const std::filesystem::path file_ = tmp_.path() / "options.yaml";
};

TEST_F(PipelineOptionsFile, ValuesReachTheirStructsAndTheRestKeepDefaults) {
  auto options = Read(
      "pipeline:\n"
      "  tag_search: every_frame\n"
      "  detector: {quad_decimate: 1.5, refinement: apriltag}\n"
      "  tracker: {full_frame_every: 7}\n"
      "  recon:\n    keyframe_min_rotation_deg: 2.5\n    tag_size_sigma_rel: 0.001\n    pose: {max_rms_px: 3}\n"
      "    ba: {window_keyframes: 5}\n"
      "  features: {enabled: false, depth_range_factor: 3, extractor: {max_features: 500},\n"
      "             map: {max_neighbours: 5, triangulation: {min_views: 3}}}\n"
      "  feedback: {point_error_goal_m: 0.002}\n");
  ASSERT_TRUE(options) << options.error().message;
  const PipelineOptions defaults;
  EXPECT_EQ(options->tag_search, TagSearch::kEveryFrame);
  EXPECT_FLOAT_EQ(options->detector.quad_decimate, 1.5f);
  EXPECT_EQ(options->detector.refinement, CornerRefinement::kAprilTag);
  EXPECT_EQ(options->detector.threads, defaults.detector.threads);
  EXPECT_EQ(options->tracker.full_frame_every, 7);
  EXPECT_DOUBLE_EQ(options->recon.keyframe_min_rotation_deg, 2.5);
  EXPECT_DOUBLE_EQ(options->recon.tag_size_sigma_rel, 0.001);
  EXPECT_DOUBLE_EQ(options->recon.pose.max_rms_px, 3.0);
  EXPECT_EQ(options->recon.ba.window_keyframes, 5);
  EXPECT_DOUBLE_EQ(options->recon.ba.huber_px, defaults.recon.ba.huber_px);
  EXPECT_FALSE(options->features.enabled);
  EXPECT_EQ(options->features.extractor.max_features, 500);
  EXPECT_EQ(options->features.map.max_neighbours, 5);
  EXPECT_EQ(options->features.map.triangulation.min_views, 3);
  EXPECT_DOUBLE_EQ(options->features.depth_range_factor, 3.0);
  EXPECT_DOUBLE_EQ(options->features.map.matcher.ratio, defaults.features.map.matcher.ratio);
  EXPECT_DOUBLE_EQ(options->feedback.point_error_goal_m, 0.002);
}

TEST_F(PipelineOptionsFile, NoBlockGivesTheDefaults) {
  auto options = Read("run:\n  record_dir: x\n");
  ASSERT_TRUE(options) << options.error().message;
  EXPECT_EQ(options->tag_search, TagSearch::kTracking);
  EXPECT_TRUE(options->features.enabled);
}

TEST_F(PipelineOptionsFile, WrongValuesNameTheFileAndTheField) {
  const std::string f = file_.string() + ": ";
  EXPECT_EQ(ErrorOf("pipeline:\n  recon:\n    ba:\n      huber_px: soft\n"), f + "pipeline.recon.ba.huber_px: expected a number");
  EXPECT_EQ(ErrorOf("pipeline:\n  recon:\n    ba:\n      huber_px: -1\n"), f + "pipeline.recon.ba.huber_px must be > 0");
  EXPECT_EQ(ErrorOf("pipeline:\n  recon:\n    pose: {max_rms_px: 0}\n"), f + "pipeline.recon.pose.max_rms_px must be > 0");
  EXPECT_EQ(ErrorOf("pipeline:\n  recon: {max_pending_views: 0}\n"), f + "pipeline.recon.max_pending_views must be >= 1");
  EXPECT_EQ(ErrorOf("pipeline:\n  tracker: {full_frame_every: 2.5}\n"),
            f + "pipeline.tracker.full_frame_every: expected a whole number");
  EXPECT_EQ(ErrorOf("pipeline:\n  tracker: {ful_frame_every: 2}\n"), f + "pipeline.tracker.ful_frame_every: unknown field");
  EXPECT_EQ(ErrorOf("pipeline:\n  features: {enabled: maybe}\n"), f + "pipeline.features.enabled: expected true or false");
  EXPECT_EQ(ErrorOf("pipeline:\n  features: {map: {triangulation: {min_views: 1}}}\n"),
            f + "pipeline.features.map.triangulation.min_views must be >= 2");
  EXPECT_EQ(ErrorOf("pipeline:\n  features: {map: {matcher: {ratio: 2}}}\n"),
            f + "pipeline.features.map.matcher.ratio must be in (0, 1]");
  EXPECT_EQ(ErrorOf("pipeline:\n  features: {map: {min_overlap: 2}}\n"), f + "pipeline.features.map.min_overlap must be in [0, 1]");
  EXPECT_EQ(ErrorOf("pipeline:\n  features: {extractor: {image_scale: 0}}\n"),
            f + "pipeline.features.extractor.image_scale must be in (0.1, 1]");
  EXPECT_EQ(ErrorOf("pipeline:\n  features: {depth_range_factor: 1}\n"),
            f + "pipeline.features.depth_range_factor must be in (1, 1000)");
  EXPECT_EQ(ErrorOf("pipeline:\n  features: {map: {refinement: {half_window: 1}}}\n"),
            f + "pipeline.features.map.refinement.half_window must be in [2, 32]");
  EXPECT_EQ(ErrorOf("pipeline:\n  features: {finish_threads: 0}\n"), f + "pipeline.features.finish_threads must be in [1, 64]");
  EXPECT_EQ(ErrorOf("pipeline:\n  feedback: {point_error_goal_m: .nan}\n"),
            f + "pipeline.feedback.point_error_goal_m: expected a number");
  EXPECT_EQ(ErrorOf("pipeline:\n  detector: 3\n"), f + "pipeline.detector: expected a block of fields");
  EXPECT_NE(ErrorOf("pipeline:\n  tag_search: sometimes\n").find(f + "pipeline.tag_search: "), std::string::npos);
  EXPECT_NE(ErrorOf("pipeline:\n  detector: {refinement: best}\n").find(f + "pipeline.detector.refinement: "),
            std::string::npos);
  EXPECT_EQ(ErrorOf("pipeline: [\n"), f + "not valid YAML");
}

// firmware_config/README.md lists every field with its default: the block
// must read (no unknown field) and give the defaults.
TEST_F(PipelineOptionsFile, TheDocumentedBlockReadsAndHoldsTheDefaults) {
  const auto readme = std::filesystem::path(TAGSFM_RECORDINGS_DIR) / ".." / "firmware_config" / "README.md";
  std::ifstream in(readme);
  ASSERT_TRUE(in) << readme;
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t start = text.find("```yaml\npipeline:");
  ASSERT_NE(start, std::string::npos) << "no pipeline: block in " << readme;
  const size_t end = text.find("```", start + 7);
  auto options = Read(text.substr(start + 8, end - start - 8));
  ASSERT_TRUE(options) << options.error().message;
  const PipelineOptions defaults;
  EXPECT_FLOAT_EQ(options->detector.quad_decimate, defaults.detector.quad_decimate);
  EXPECT_EQ(options->detector.refinement, defaults.detector.refinement);
  EXPECT_EQ(options->tracker.full_frame_every, defaults.tracker.full_frame_every);
  EXPECT_DOUBLE_EQ(options->tracker.entry_min_inflow_px, defaults.tracker.entry_min_inflow_px);
  EXPECT_DOUBLE_EQ(options->recon.keyframe_min_translation_ratio, defaults.recon.keyframe_min_translation_ratio);
  EXPECT_DOUBLE_EQ(options->recon.tag_size_sigma_rel, defaults.recon.tag_size_sigma_rel);
  EXPECT_DOUBLE_EQ(options->recon.pose.ransac_threshold_px, defaults.recon.pose.ransac_threshold_px);
  EXPECT_EQ(options->recon.ba.window_keyframes, defaults.recon.ba.window_keyframes);
  EXPECT_EQ(options->features.extractor.max_features, defaults.features.extractor.max_features);
  EXPECT_DOUBLE_EQ(options->features.extractor.contrast_threshold, defaults.features.extractor.contrast_threshold);
  EXPECT_DOUBLE_EQ(options->features.map.triangulation.min_angle_deg, defaults.features.map.triangulation.min_angle_deg);
  EXPECT_DOUBLE_EQ(options->features.map.triangulation.max_relative_sigma,
                   defaults.features.map.triangulation.max_relative_sigma);
  EXPECT_DOUBLE_EQ(options->features.depth_range_factor, defaults.features.depth_range_factor);
  EXPECT_EQ(options->features.finish_threads, defaults.features.finish_threads);
  EXPECT_EQ(options->features.map.refine, defaults.features.map.refine);
  EXPECT_DOUBLE_EQ(options->features.map.first_pass_max_reprojection_rms_px,
                   defaults.features.map.first_pass_max_reprojection_rms_px);
  EXPECT_DOUBLE_EQ(options->features.map.refined_feature_sigma_px, defaults.features.map.refined_feature_sigma_px);
  EXPECT_EQ(options->features.map.refinement.half_window, defaults.features.map.refinement.half_window);
  EXPECT_DOUBLE_EQ(options->features.map.refinement.min_correlation, defaults.features.map.refinement.min_correlation);
  EXPECT_DOUBLE_EQ(options->feedback.point_error_goal_m, defaults.feedback.point_error_goal_m);
}

// Found by the run_config fuzz target: a file whose top level is a scalar
// or a list, or a field whose name is not text, made yaml-cpp throw.
TEST_F(PipelineOptionsFile, ATopLevelThatIsNoMappingOrAKeyThatIsNoTextIsAOneLineError) {
  const std::string expected = file_.string() + ": the top level must be a mapping of blocks";
  EXPECT_EQ(ErrorOf("captur\xff\xff\xff" "min_overlap\n"), expected);  // the fuzzer's input, shortened
  EXPECT_EQ(ErrorOf("- pipeline\n- 3\n"), expected);
  EXPECT_TRUE(Read("")) << "an empty file keeps the defaults";
  // A complex key ("? [a, b]") made the unknown-field check throw.
  EXPECT_EQ(ErrorOf("pipeline:\n  recon:\n    ? [a, b]\n    : 5\n"),
            file_.string() + ": pipeline.recon.[a, b]: unknown field");
}

TEST(PipelineOptionsFileMissing, IsNamed) {
  auto options = ReadPipelineOptionsFile("/nonexistent/options.yaml");
  ASSERT_FALSE(options);
  EXPECT_EQ(options.error().message, "/nonexistent/options.yaml: cannot be read");
}

}  // namespace
}  // namespace tagsfm
