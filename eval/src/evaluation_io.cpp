// Loading OUT/ and REC/ for the evaluation, and its JSON.
#include <nlohmann/json.hpp>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/eval/colmap_model.h"
#include "tagsfm/eval/evaluation.h"
#include "tagsfm/eval/ply_reader.h"
#include "tagsfm/export/feature_points_csv.h"
#include "tagsfm/export/target_covariance_csv.h"

namespace tagsfm::eval {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

// Loads an optional file: absent is fine (nullopt), malformed is an error.
template <class T, class Loader>
Status LoadOptional(const fs::path& path, Loader load, std::optional<T>* out, json* presence, const std::string& key) {
  std::error_code ec;
  const bool present = fs::is_regular_file(path, ec);
  (*presence)[key] = present;
  if (!present) return Status::Ok();
  Result<T> value = load(path);
  if (!value) return value.error();
  *out = std::move(*value);
  return Status::Ok();
}

json StatsJson(const Stats& s) {
  if (s.count == 0) return json{{"count", 0}};
  return json{{"count", s.count}, {"mean", s.mean}, {"median", s.median}, {"p95", s.p95}, {"max", s.max}, {"rms", s.rms}};
}

json Vector(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

json VariantJson(const AlignedErrors& v) {
  json out;
  if (v.poses) {
    json frames = json::array();
    for (const FrameError& f : v.poses->frames) {
      frames.push_back({{"frame", f.frame},
                        {"reprojection_px", f.reprojection_px ? json(*f.reprojection_px) : json(nullptr)},
                        {"rotation_rel", f.rotation_rel},
                        {"rotation_deg", f.rotation_deg},
                        {"position_m", f.position_m}});
    }
    out["poses"] = {{"reprojection_px", StatsJson(v.poses->reprojection_px)},
                    {"rotation_rel", StatsJson(v.poses->rotation_rel)},
                    {"rotation_deg", StatsJson(v.poses->rotation_deg)},
                    {"position_m", StatsJson(v.poses->position_m)},
                    {"per_frame", frames}};
  } else {
    out["poses"] = nullptr;
  }
  out["targets"] = v.targets ? json{{"common_tags", v.targets->common_tags},
                                    {"corner_error_m", StatsJson(v.targets->corner_error_m)}}
                             : json(nullptr);
  out["cloud_distance_m"] = v.cloud_distance_m ? StatsJson(*v.cloud_distance_m) : json(nullptr);
  out["feature_points"] = v.feature_points ? json{{"count", v.feature_points->distance_m.count},
                                                  {"distance_m", StatsJson(v.feature_points->distance_m)},
                                                  {"within_1mm", v.feature_points->within_1mm},
                                                  {"within_2mm", v.feature_points->within_2mm},
                                                  {"within_5mm", v.feature_points->within_5mm}}
                                           : json(nullptr);
  return out;
}

json MapJson(const MapPrecision& m) {
  return {{"scene_size_m", m.scene_size_m},
          {"rigid_rms_m", m.rigid_rms_m},
          {"rigid_ratio", m.rigid_ratio},
          {"similarity_rms_m", m.similarity_rms_m},
          {"similarity_ratio", m.similarity_ratio},
          {"scale_error_ppm", m.scale_error_ppm}};
}

// VDI/VDE 2634-1 style: every tag pair's length, its error and sigma.
json LengthsJson(const LengthErrors& l) {
  json pairs = json::array();
  for (const LengthError& p : l.pairs) {
    pairs.push_back({{"a", p.a},
                     {"b", p.b},
                     {"true_length_m", p.true_length_m},
                     {"measured_length_m", p.measured_length_m},
                     {"error_m", p.error_m},
                     {"sigma_m", p.sigma_m ? json(*p.sigma_m) : json(nullptr)}});
  }
  json out = {{"count", l.pairs.size()},
              {"abs_error_m", StatsJson(l.abs_error_m)},
              {"error_per_length_ppm", l.error_per_length_ppm},
              {"weighted_error_per_length_ppm",
               l.weighted_error_per_length_ppm ? json(*l.weighted_error_per_length_ppm) : json(nullptr)},
              {"pairs", pairs}};
  out["error_over_sigma"] = l.normalized_count > 0 ? json{{"count", l.normalized_count},
                                                           {"mean", l.normalized_mean},
                                                           {"std", l.normalized_std},
                                                           {"beyond_3_sigma", l.beyond_3_sigma}}
                                                     : json(nullptr);
  return out;
}

json EvaluationJson(const Evaluation& e) {
  json out;
  out["frames"] = {{"ground_truth", e.ground_truth_frames},
                   {"registered", e.registered_frames},
                   {"unregistered", e.unregistered_frames},
                   {"not_in_ground_truth", e.unknown_frames}};
  out["tags"] = {{"missing", e.missing_tags}, {"not_in_ground_truth", e.unknown_tags}};
  out["cloud_points"] = e.cloud_points;
  out["feature_points"] = {{"count", e.feature_points},
                           {"mean_reprojection_px", e.feature_mean_reprojection_px
                                                        ? json(*e.feature_mean_reprojection_px)
                                                        : json(nullptr)}};
  json alignment = {{"source", e.alignment_source}, {"correspondences", e.alignment_correspondences}};
  for (const AlignedErrors& v : e.variants) {
    out[v.name] = VariantJson(v);
    if (v.name == "as_is") continue;
    alignment[v.name] = {{"scale", v.true_from_est.scale},
                         {"rotation_deg", RotationAngleDeg(v.true_from_est.rotation, Eigen::Quaterniond::Identity())},
                         {"translation_m", Vector(v.true_from_est.translation)},
                         {"scale_error_ppm", (v.true_from_est.scale - 1.0) * 1e6}};
  }
  out["alignment"] = alignment;
  out["map"] = e.map ? MapJson(*e.map) : json(nullptr);
  out["lengths"] = e.lengths ? LengthsJson(*e.lengths) : json(nullptr);
  for (const char* name : {"rigid", "similarity"}) {
    if (!out.contains(name)) out[name] = nullptr;
  }
  return out;
}

std::vector<ScoredPoint> FromFeaturesCsv(const std::map<long long, StoredFeaturePoint>& stored) {
  std::vector<ScoredPoint> points;
  points.reserve(stored.size());
  for (const auto& [id, p] : stored) points.push_back({p.position, p.reprojection_rms_px});
  return points;
}

// A COLMAP text model as OUT: poses by frames.csv's file names, its points
// as the cloud and the feature points (COLMAP's ERROR is a per-point mean).
Status LoadColmapModel(const fs::path& dir, const fs::path& rec_dir, EvaluationInput* in, json* result_files) {
  Result<ColmapModel> model = ReadColmapTextModel(dir);
  if (!model) return model.error();
  Result<RecordingReader> recording = RecordingReader::Open(rec_dir);
  if (!recording) return recording.error();
  ColmapFramePoses poses = MatchImagesToFrames(*model, recording->entries(), rec_dir);
  in->estimated_poses = std::move(poses.cam_from_world);
  std::vector<Eigen::Vector3d> cloud;
  std::vector<ScoredPoint> features;
  for (const ColmapPoint& p : model->points) {
    cloud.push_back(p.xyz);
    features.push_back({p.xyz, p.error_px});
  }
  in->cloud = std::move(cloud);
  in->feature_points = std::move(features);
  (*result_files)["cameras.txt"] = !model->cameras.empty();
  (*result_files)["images.txt"] = true;
  (*result_files)["points3D.txt"] = true;
  (*result_files)["colmap_images"] = model->images_by_name.size();
  (*result_files)["colmap_images_not_in_frames_csv"] = poses.unmatched_images;
  return Status::Ok();
}

}  // namespace

Result<std::string> EvaluateDirectoriesJson(const fs::path& out_dir, const fs::path& rec_dir) {
  std::error_code ec;
  if (!fs::is_directory(out_dir, ec)) return MakeError(out_dir.string() + ": not a directory (the replay's output)");
  const fs::path truth = rec_dir / "ground_truth";
  if (!fs::is_directory(truth, ec)) {
    return MakeError(truth.string() + ": missing; evaluate needs a recording with ground truth");
  }
  EvaluationInput in;
  json files = {{"result", json::object()}, {"ground_truth", json::object()}};
  Result<RecordingInfo> info = ReadRecordingYaml(rec_dir / "recording.yaml");
  if (!info) return info.error();
  in.camera = info->camera;
  json& result_files = files["result"];
  json& truth_files = files["ground_truth"];
  Status s = LoadOptional(truth / "poses.csv", ReadPosesCsv, &in.true_poses, &truth_files, "poses.csv");
  if (s) s = LoadOptional(truth / "targets.csv", ReadTargetsCsv, &in.true_targets, &truth_files, "targets.csv");
  if (s) s = LoadOptional(truth / "scene.yaml", ReadSceneYaml, &in.surfaces, &truth_files, "scene.yaml");
  const bool colmap = IsColmapTextModel(out_dir);
  if (colmap) {
    if (s) s = LoadColmapModel(out_dir, rec_dir, &in, &result_files);
  } else {
    if (s) s = LoadOptional(out_dir / "poses.csv", ReadPosesCsv, &in.estimated_poses, &result_files, "poses.csv");
    if (s) s = LoadOptional(out_dir / "targets.csv", ReadTargetsCsv, &in.estimated_targets, &result_files, "targets.csv");
    if (s) s = LoadOptional(out_dir / "cloud.ply", ReadPlyPoints, &in.cloud, &result_files, "cloud.ply");
    std::optional<std::map<long long, StoredFeaturePoint>> features;
    if (s) s = LoadOptional(out_dir / "features.csv", ReadFeaturePointsCsv, &features, &result_files, "features.csv");
    if (features) in.feature_points = FromFeaturesCsv(*features);
    if (s) {
      s = LoadOptional(out_dir / "targets_cov.csv", ReadTargetCovariance, &in.target_covariance, &result_files,
                       "targets_cov.csv");
    }
  }
  if (!s) return s.error();

  json report = nullptr;
  const fs::path report_path = out_dir / "report.json";
  result_files["report.json"] = !colmap && fs::is_regular_file(report_path, ec);
  if (result_files["report.json"]) {
    Result<std::string> text = ReadFileToString(report_path);
    if (!text) return text.error();
    report = json::parse(*text, nullptr, /*allow_exceptions=*/false);
    if (report.is_discarded()) return MakeError(report_path.string() + ": not valid JSON");
  }

  if (report.is_object() && report.contains("scale") && report["scale"].is_object() && report["scale"]["sigma_rel"].is_number()) {
    in.scale_sigma_rel = report["scale"]["sigma_rel"].get<double>();
  }
  json out = EvaluationJson(Evaluate(in));
  out["out"] = out_dir.string();
  out["rec"] = rec_dir.string();
  out["result_format"] = colmap ? "colmap_text" : "tagsfm";
  if (in.feature_points) {
    out["feature_points"]["source"] = colmap ? "points3D.txt" : "features.csv";
    out["feature_points"]["reprojection_is"] =
        colmap ? "mean over points of points3D.txt's ERROR (each point's mean over its track)"
               : "mean over points of features.csv's reprojection_rms_px (each point's RMS over its track)";
  } else {
    out["feature_points"]["source"] = nullptr;
  }
  out["files"] = files;
  out["report"] = report;
  return out.dump(2) + "\n";
}

}  // namespace tagsfm::eval
