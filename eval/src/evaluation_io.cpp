// Loading OUT/ and REC/ for the evaluation, and its JSON.
#include <nlohmann/json.hpp>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/eval/evaluation.h"
#include "tagsfm/eval/ply_reader.h"

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
  json alignment = {{"source", e.alignment_source}, {"correspondences", e.alignment_correspondences}};
  for (const AlignedErrors& v : e.variants) {
    out[v.name] = VariantJson(v);
    if (v.name == "as_is") continue;
    alignment[v.name] = {{"scale", v.true_from_est.scale},
                         {"rotation_deg", RotationAngleDeg(v.true_from_est.rotation, Eigen::Quaterniond::Identity())},
                         {"translation_m", Vector(v.true_from_est.translation)}};
  }
  out["alignment"] = alignment;
  for (const char* name : {"rigid", "similarity"}) {
    if (!out.contains(name)) out[name] = nullptr;
  }
  return out;
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
  if (s) s = LoadOptional(out_dir / "poses.csv", ReadPosesCsv, &in.estimated_poses, &result_files, "poses.csv");
  if (s) s = LoadOptional(out_dir / "targets.csv", ReadTargetsCsv, &in.estimated_targets, &result_files, "targets.csv");
  if (s) s = LoadOptional(out_dir / "cloud.ply", ReadPlyPoints, &in.cloud, &result_files, "cloud.ply");
  if (!s) return s.error();

  json report = nullptr;
  const fs::path report_path = out_dir / "report.json";
  result_files["report.json"] = fs::is_regular_file(report_path, ec);
  if (result_files["report.json"]) {
    Result<std::string> text = ReadFileToString(report_path);
    if (!text) return text.error();
    report = json::parse(*text, nullptr, /*allow_exceptions=*/false);
    if (report.is_discarded()) return MakeError(report_path.string() + ": not valid JSON");
  }

  json out = EvaluationJson(Evaluate(in));
  out["out"] = out_dir.string();
  out["rec"] = rec_dir.string();
  out["files"] = files;
  out["report"] = report;
  return out.dump(2) + "\n";
}

}  // namespace tagsfm::eval
