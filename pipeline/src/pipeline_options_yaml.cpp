// The `pipeline:` block: one reader per options struct, field names as in
// the structs.
#include "tagsfm/pipeline/pipeline_options.h"
#include "yaml_fields.h"

namespace tagsfm {
namespace {

void ReadDetector(YamlFields f, TagDetectorOptions* o) {
  f.Read("quad_decimate", &o->quad_decimate);
  f.Read("quad_sigma", &o->quad_sigma);
  f.Read("threads", &o->threads);
  f.Read("refine_edges", &o->refine_edges);
  f.Read("decode_sharpening", &o->decode_sharpening);
  f.ReadChoice<CornerRefinement>("refinement", &o->refinement, ParseCornerRefinement);
  f.Read("min_decision_margin", &o->min_decision_margin);
  f.Read("max_hamming", &o->max_hamming);
  f.Read("small_tag_pass", &o->small_tag_pass);
  f.Read("small_tag_min_margin", &o->small_tag_min_margin);
  f.Done();
}

void ReadTracker(YamlFields f, TagTrackerOptions* o) {
  f.Read("full_frame_every", &o->full_frame_every);
  f.Read("full_frame_after_motion", &o->full_frame_after_motion);
  f.Read("padding_px", &o->padding_px);
  f.Read("padding_fraction", &o->padding_fraction);
  f.Read("region_quad_decimate", &o->region_quad_decimate);
  f.Read("region_coarse_module_px", &o->region_coarse_module_px);
  f.Read("search_entry_bands", &o->search_entry_bands);
  f.Read("entry_band_tag_sizes", &o->entry_band_tag_sizes);
  f.Read("entry_band_margin_px", &o->entry_band_margin_px);
  f.Read("entry_band_inflow_frames", &o->entry_band_inflow_frames);
  f.Read("entry_band_candidates", &o->entry_band_candidates);
  f.Read("entry_band_candidates_min_module_px", &o->entry_band_candidates_min_module_px);
  f.Read("entry_min_inflow_px", &o->entry_min_inflow_px);
  f.Read("fine_search_below_tags", &o->fine_search_below_tags);
  f.Read("back_off_after_recovery", &o->back_off_after_recovery);
  f.Done();
}

void ReadPose(YamlFields f, PoseEstimatorOptions* o) {
  f.Read("ransac_threshold_px", &o->ransac_threshold_px);
  f.Read("ransac_iterations", &o->ransac_iterations);
  f.Read("ransac_confidence", &o->ransac_confidence);
  f.Read("max_rms_px", &o->max_rms_px);
  f.Read("corner_sigma_px", &o->corner_sigma_px);
  f.Read("rms_sigmas", &o->rms_sigmas);
  f.Read("outlier_sigmas", &o->outlier_sigmas);
  f.Read("min_outlier_px", &o->min_outlier_px);
  f.Read("min_inlier_ratio", &o->min_inlier_ratio);
  f.Read("max_rotation_jump_deg", &o->max_rotation_jump_deg);
  f.Read("planarity_ratio", &o->planarity_ratio);
  f.Read("huber_px", &o->huber_px);
  f.Read("refine_iterations", &o->refine_iterations);
  f.Done();
}

void ReadAdjustment(YamlFields f, BundleAdjusterOptions* o) {
  f.Read("window_keyframes", &o->window_keyframes);
  f.Read("window_iterations", &o->window_iterations);
  f.Read("global_iterations", &o->global_iterations);
  f.Read("huber_px", &o->huber_px);
  f.Read("global_threads", &o->global_threads);
  f.Read("window_threads", &o->window_threads);
  f.Read("compute_covariance", &o->compute_covariance);
  f.Done();
}

void ReadRecon(YamlFields f, ReconstructorOptions* o) {
  ReadPose(f.Block("pose"), &o->pose);
  ReadAdjustment(f.Block("ba"), &o->ba);
  f.Read("min_tag_view_angle_deg", &o->min_tag_view_angle_deg);
  f.Read("max_pending_views", &o->max_pending_views);
  f.Read("max_tag_init_rms_px", &o->max_tag_init_rms_px);
  f.Read("remap_after_outlier_frames", &o->remap_after_outlier_frames);
  f.Read("bootstrap_max_frames", &o->bootstrap_max_frames);
  f.Read("max_retained_frames", &o->max_retained_frames);
  f.Read("bootstrap_min_angle_deg", &o->bootstrap_min_angle_deg);
  f.Read("keyframe_min_translation_ratio", &o->keyframe_min_translation_ratio);
  f.Read("keyframe_min_rotation_deg", &o->keyframe_min_rotation_deg);
  f.Read("final_adjustment", &o->final_adjustment);
  f.Read("points_refit_shift_px", &o->points_refit_shift_px);
  f.Read("max_points_refits", &o->max_points_refits);
  f.Read("tie_points_per_keyframe", &o->tie_points_per_keyframe);
  f.Read("points_threads", &o->points_threads);
  f.Read("refine_intrinsics", &o->refine_intrinsics);
  f.Read("tag_size_sigma_rel", &o->tag_size_sigma_rel);
  f.Read("weight_corners", &o->weight_corners);
  f.Read("corner_sigma_reference_px", &o->corner_sigma_reference_px);
  f.Read("corner_sigma_floor_px", &o->corner_sigma_floor_px);
  f.Done();
}

void ReadExtractor(YamlFields f, FeatureExtractorOptions* o) {
  f.Read("max_features", &o->max_features);
  f.Read("contrast_threshold", &o->contrast_threshold);
  f.Read("contrast_relative_to_range", &o->contrast_relative_to_range);
  f.Read("min_features_per_megapixel", &o->min_features_per_megapixel);
  f.Read("min_contrast_threshold", &o->min_contrast_threshold);
  f.Read("root_sift", &o->root_sift);
  f.Read("tag_margin", &o->tag_margin);
  f.Read("image_scale", &o->image_scale);
  f.Done();
}

void ReadMatcher(YamlFields f, GuidedMatcherOptions* o) {
  f.Read("epipolar_px", &o->epipolar_px);
  f.Read("ratio", &o->ratio);
  f.Read("max_descriptor_distance", &o->max_descriptor_distance);
  f.Read("grid_cell_px", &o->grid_cell_px);
  f.Done();
}

void ReadTriangulation(YamlFields f, TrackTriangulationOptions* o) {
  f.Read("min_views", &o->min_views);
  f.Read("min_angle_deg", &o->min_angle_deg);
  f.Read("max_view_error_px", &o->max_view_error_px);
  f.Read("max_reprojection_rms_px", &o->max_reprojection_rms_px);
  f.Read("feature_sigma_px", &o->feature_sigma_px);
  f.Read("max_relative_sigma", &o->max_relative_sigma);
  f.Read("max_iterations", &o->max_iterations);
  f.Done();
}

void ReadRefinement(YamlFields f, PatchRefinementOptions* o) {
  f.Read("half_window", &o->half_window);
  f.Read("max_iterations", &o->max_iterations);
  f.Read("converged_px", &o->converged_px);
  f.Read("converged_sigma_fraction", &o->converged_sigma_fraction);
  f.Read("sparse_until_px", &o->sparse_until_px);
  f.Read("reference_attempts", &o->reference_attempts);
  f.Read("tilt_retries", &o->tilt_retries);
  f.Read("tilt_step_deg", &o->tilt_step_deg);
  f.Read("max_shift_px", &o->max_shift_px);
  f.Read("min_correlation", &o->min_correlation);
  f.Read("max_sigma_px", &o->max_sigma_px);
  f.Read("balance_scale", &o->balance_scale);
  f.Read("max_level", &o->max_level);
  f.Done();
}

void ReadFeatureMap(YamlFields f, FeatureMapOptions* o) {
  ReadMatcher(f.Block("matcher"), &o->matcher);
  ReadTriangulation(f.Block("triangulation"), &o->triangulation);
  f.Read("refine", &o->refine);
  ReadRefinement(f.Block("refinement"), &o->refinement);
  f.Read("first_pass_max_reprojection_rms_px", &o->first_pass_max_reprojection_rms_px);
  f.Read("refined_feature_sigma_px", &o->refined_feature_sigma_px);
  f.Read("keep_unrefined_views", &o->keep_unrefined_views);
  f.Read("epipolar_fallback", &o->epipolar_fallback);
  f.Read("max_fit_sigma_per_epipolar_sigma", &o->max_fit_sigma_per_epipolar_sigma);
  f.Read("max_neighbours", &o->max_neighbours);
  f.Read("min_overlap", &o->min_overlap);
  f.Read("max_view_angle_deg", &o->max_view_angle_deg);
  f.Read("rematch_shift_px", &o->rematch_shift_px);
  f.Done();
}

void ReadFeatures(YamlFields f, FeatureStageOptions* o) {
  f.Read("enabled", &o->enabled);
  f.Read("background", &o->background);
  f.Read("max_queued_keyframes", &o->max_queued_keyframes);
  ReadExtractor(f.Block("extractor"), &o->extractor);
  ReadFeatureMap(f.Block("map"), &o->map);
  f.Read("max_feature_image_side", &o->max_feature_image_side);
  f.Read("depth_range_factor", &o->depth_range_factor);
  f.Read("fallback_near_m", &o->fallback_near_m);
  f.Read("fallback_far_m", &o->fallback_far_m);
  f.Read("live_cloud_interval_s", &o->live_cloud_interval_s);
  f.Read("live_cloud_max_points", &o->live_cloud_max_points);
  f.Read("finish_threads", &o->finish_threads);
  f.Read("match_threads", &o->match_threads);
  f.Read("rematch_final_poses", &o->rematch_final_poses);
  f.Done();
}

void ReadFeedback(YamlFields f, LiveFeedbackOptions* o) {
  f.Read("point_error_goal_m", &o->point_error_goal_m);
  f.Read("baseline_angle_deg", &o->baseline_angle_deg);
  f.Read("min_targets_in_view", &o->min_targets_in_view);
  f.Read("min_views_per_target", &o->min_views_per_target);
  f.Read("min_direction_spread_deg", &o->min_direction_spread_deg);
  f.Read("min_image_noise_px", &o->min_image_noise_px);
  f.Done();
}

}  // namespace

Status ReadPipelineOptions(const YAML::Node& block, const std::filesystem::path& file, PipelineOptions* options) {
  Status status;
  YamlFields f(block, "pipeline", file, &status);
  f.ReadChoice<TagSearch>("tag_search", &options->tag_search, ParseTagSearch);
  ReadDetector(f.Block("detector"), &options->detector);
  ReadTracker(f.Block("tracker"), &options->tracker);
  ReadRecon(f.Block("recon"), &options->recon);
  ReadFeatures(f.Block("features"), &options->features);
  ReadFeedback(f.Block("feedback"), &options->feedback);
  f.Done();
  if (!status) return status;
  if (Status s = options->Check(); !s) return MakeError(file.string() + ": " + s.error().message);
  return Status::Ok();
}

Result<PipelineOptions> ReadPipelineOptionsFile(const std::filesystem::path& file) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(file.string());
  } catch (const YAML::BadFile&) {
    return MakeError(file.string() + ": cannot be read");
  } catch (const YAML::Exception&) {
    return MakeError(file.string() + ": not valid YAML");
  }
  // A scalar or list at the top has no `pipeline` key: yaml-cpp throws on
  // the lookup (found by the run_config fuzz target).
  if (!root.IsNull() && !root.IsMap()) return MakeError(file.string() + ": the top level must be a mapping of blocks");
  PipelineOptions options;
  if (Status s = ReadPipelineOptions(root["pipeline"], file, &options); !s) return s.error();
  return options;
}

}  // namespace tagsfm
