#include "tagsfm/recon/result_writer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <sstream>

#include <nlohmann/json.hpp>

#include "tagsfm/core/file_util.h"
#include "tagsfm/recon/feature_points_csv.h"

namespace tagsfm {
namespace {

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const size_t index = std::min(values.size() - 1, static_cast<size_t>(std::ceil(q * values.size())) - (q > 0 ? 1 : 0));
  return values[index];
}

nlohmann::json LatencyJson(const std::vector<double>& ms) {
  return {{"p50", Percentile(ms, 0.5)}, {"p95", Percentile(ms, 0.95)},
          {"max", ms.empty() ? 0.0 : *std::max_element(ms.begin(), ms.end())}};
}

std::string FrameName(const RunStats& stats, FrameId frame) {
  auto it = stats.image_names.find(frame);
  if (it != stats.image_names.end()) return it->second;
  std::ostringstream name;
  name << "frame_" << std::setw(6) << std::setfill('0') << frame;
  return name.str();
}

// COLMAP's point id of a tag corner (ids start at 1).
long long CornerPointId(TagId id, int corner) { return 4LL * id + corner + 1; }

}  // namespace

double PeakRssMb() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;  // kB
  }
  return 0;
}

std::map<std::pair<TagId, int>, CornerStats> ComputeCornerStats(const ReconstructionResult& result) {
  std::map<std::pair<TagId, int>, std::pair<double, int>> sums;
  std::map<TagId, TagCorners> corners;
  for (const auto& [id, tag] : result.tags) corners[id] = tag.CornersInWorld();
  for (const auto& frame : result.frames) {
    if (!frame.registered) continue;
    const Rigid3d cam_from_world = frame.cam_from_world.ToRigid();
    for (const auto& obs : frame.tags) {
      auto it = corners.find(obs.id);
      if (it == corners.end()) continue;
      for (int k = 0; k < 4; ++k) {
        auto& [sum, n] = sums[{obs.id, k}];
        sum += (result.camera.Project(cam_from_world * it->second[k]) - obs.pixels[k]).squaredNorm();
        ++n;
      }
    }
  }
  std::map<std::pair<TagId, int>, CornerStats> out;
  for (const auto& [key, sn] : sums) out[key] = {std::sqrt(sn.first / sn.second), sn.second};
  return out;
}

Status WriteReport(const std::filesystem::path& path, const ReconstructionResult& result, const RunStats& stats) {
  nlohmann::json report;
  int registered = 0;
  std::map<TagId, bool> seen;
  nlohmann::json unregistered = nlohmann::json::array();
  for (const auto& f : result.frames) {
    for (const auto& obs : f.tags) seen[obs.id] = true;
    if (f.registered) {
      ++registered;
    } else {
      unregistered.push_back({{"frame", f.frame}, {"reason", f.reason}});
    }
  }
  nlohmann::json skipped = nlohmann::json::array();
  for (const auto& [frame, why] : stats.skipped) skipped.push_back({{"frame", frame}, {"reason", why}});
  report["frames"] = stats.frames;
  report["registered_frames"] = registered;
  report["frames_skipped"] = stats.frames_skipped;
  report["targets_seen"] = seen.size();
  report["targets_mapped"] = result.tags.size();
  report["points"] = 4 * result.tags.size() + result.feature_points.size();
  report["feature_points"] = result.feature_points.size();
  report["observations"] = result.observations;
  report["outlier_observations"] = result.outlier_observations;  // tag views left out of the adjustment
  report["tags_remapped"] = result.tags_remapped;                // learned tags mapped again while running
  // All observations: target corners and feature points together.
  double sum_sq = result.reprojection_rms_px * result.reprojection_rms_px * result.observations;
  double feature_sum_sq = 0;
  size_t count = static_cast<size_t>(result.observations), feature_count = 0;
  for (const FeaturePoint& p : result.feature_points) {
    feature_sum_sq += p.reprojection_rms_px * p.reprojection_rms_px * static_cast<double>(p.observations.size());
    feature_count += p.observations.size();
  }
  sum_sq += feature_sum_sq;
  count += feature_count;
  report["reprojection_rms_px"] = count ? std::sqrt(sum_sq / static_cast<double>(count)) : 0.0;
  report["feature_reprojection_rms_px"] = feature_count ? std::sqrt(feature_sum_sq / static_cast<double>(feature_count)) : 0.0;
  report["target_reprojection_rms_px"] = result.reprojection_rms_px;
  report["runtime_s"] = stats.runtime_s;
  report["frame_latency_ms"] = LatencyJson(stats.frame_latency_ms);
  if (!stats.detection_ms.empty()) report["detection_ms"] = LatencyJson(stats.detection_ms);
  if (!stats.tag_search.empty()) {
    report["tag_search"] = {{"mode", stats.tag_search},
                            {"full_frame_detections", stats.full_frame_detections},
                            {"recoveries", stats.tag_search_recoveries}};
  }
  if (!stats.feature_ms.empty()) {
    report["feature_keyframes"] = stats.feature_ms.size();
    report["feature_ms"] = LatencyJson(stats.feature_ms);
    report["triangulation_s"] = stats.triangulation_s;
  }
  report["peak_rss_mb"] = stats.peak_rss_mb;
  report["mode"] = stats.mode;
  report["pose_methods"] = result.pose_method_counts;
  report["unregistered_frames"] = unregistered;
  report["skipped_frames"] = skipped;
  report["global_adjustment_converged"] = result.global_adjustment_converged;
  report["intrinsics_refined"] = result.intrinsics_refined;
  report["global_adjustment_s"] = result.global_adjustment_s;
  report["covariance_s"] = result.covariance_s;
  if (result.anchor_tag) report["anchor_tag"] = *result.anchor_tag;
  report["covariance"] = result.covariance ? "targets_cov.csv" : result.covariance_note;
  report["camera"] = {{"model", CameraModel::KindName(result.camera.kind)}, {"width", result.camera.width},
                      {"height", result.camera.height}, {"fx", result.camera.fx}, {"fy", result.camera.fy},
                      {"cx", result.camera.cx}, {"cy", result.camera.cy}, {"distortion", result.camera.distortion}};
  return WriteFileAtomically(path, report.dump(2) + "\n");
}

Status WriteCloudPly(const std::filesystem::path& path, const ReconstructionResult& result) {
  const auto stats = ComputeCornerStats(result);
  std::ostringstream header;
  header << "ply\nformat binary_little_endian 1.0\n"
         << "comment tagsfm: target corners (vertex id = 4 * tag_id + corner), then feature points\n"
         << "element vertex " << 4 * result.tags.size() + result.feature_points.size() << "\n"
         << "property double x\nproperty double y\nproperty double z\n"
         << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
         << "property int track_length\nproperty float reprojection_error\nend_header\n";
  const std::string head = header.str();
  std::vector<unsigned char> bytes(head.begin(), head.end());
  auto append = [&bytes](const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    bytes.insert(bytes.end(), p, p + n);  // x86 and ARM rigs are little-endian
  };
  for (const auto& [id, tag] : result.tags) {
    const TagCorners corners = tag.CornersInWorld();
    for (int k = 0; k < 4; ++k) {
      append(corners[k].data(), 3 * sizeof(double));
      // Known targets blue, learned ones orange.
      const unsigned char colour[3] = {static_cast<unsigned char>(tag.known ? 40 : 255),
                                       static_cast<unsigned char>(tag.known ? 90 : 140),
                                       static_cast<unsigned char>(tag.known ? 255 : 0)};
      append(colour, 3);
      auto it = stats.find({id, k});
      const std::int32_t track = it == stats.end() ? 0 : it->second.track_length;
      const float error = it == stats.end() ? 0.0f : static_cast<float>(it->second.rms_px);
      append(&track, sizeof(track));
      append(&error, sizeof(error));
    }
  }
  for (const FeaturePoint& p : result.feature_points) {
    append(p.position.data(), 3 * sizeof(double));
    append(p.rgb.data(), 3);
    const std::int32_t track = static_cast<std::int32_t>(p.observations.size());
    const float error = static_cast<float>(p.reprojection_rms_px);
    append(&track, sizeof(track));
    append(&error, sizeof(error));
  }
  return WriteFileAtomically(path, bytes);
}

Status WriteColmapModel(const std::filesystem::path& dir, const ReconstructionResult& result, const RunStats& stats) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return MakeError(dir.string() + ": cannot create (" + ec.message() + ")");
  // COLMAP puts pixel centres at .5, tagsfm at integers: shift by half a pixel.
  const CameraModel& c = result.camera;
  std::ostringstream cameras;
  cameras << std::setprecision(17) << "# Camera list with one line of data per camera:\n"
          << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n# Number of cameras: 1\n";
  const auto coef = [&c](size_t i) { return i < c.distortion.size() ? c.distortion[i] : 0.0; };
  if (c.kind == CameraModel::Kind::kFisheye) {
    cameras << "1 OPENCV_FISHEYE " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx + 0.5
            << " " << c.cy + 0.5 << " " << coef(0) << " " << coef(1) << " " << coef(2) << " " << coef(3) << "\n";
  } else if (!c.HasDistortion()) {
    cameras << "1 PINHOLE " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx + 0.5 << " "
            << c.cy + 0.5 << "\n";
  } else if (c.distortion.size() <= 4 || (coef(4) == 0 && c.distortion.size() <= 5)) {
    cameras << "1 OPENCV " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx + 0.5 << " "
            << c.cy + 0.5 << " " << coef(0) << " " << coef(1) << " " << coef(2) << " " << coef(3) << "\n";
  } else {
    cameras << "1 FULL_OPENCV " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx + 0.5
            << " " << c.cy + 0.5;
    for (size_t i = 0; i < 8; ++i) cameras << " " << coef(i);
    cameras << "\n";
  }
  // Images: one per registered frame, its 2D points the mapped tag corners.
  std::ostringstream images;
  images << std::setprecision(17) << "# Image list with two lines of data per image:\n"
         << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
  std::map<long long, std::vector<std::pair<int, int>>> tracks;  // point id -> (image id, point2D index)
  // Feature observations by frame: (pixel, point id).
  std::map<FrameId, std::vector<std::pair<Eigen::Vector2d, long long>>> feature_views;
  for (size_t i = 0; i < result.feature_points.size(); ++i) {
    for (const auto& [frame, pixel] : result.feature_points[i].observations) {
      feature_views[frame].emplace_back(pixel, kFirstFeaturePointId + static_cast<long long>(i));
    }
  }
  int image_id = 0;
  for (const auto& f : result.frames) {
    if (!f.registered) continue;
    ++image_id;
    const Rigid3d pose = f.cam_from_world.ToRigid();
    images << image_id << " " << pose.rotation.w() << " " << pose.rotation.x() << " " << pose.rotation.y() << " "
           << pose.rotation.z() << " " << pose.translation.x() << " " << pose.translation.y() << " "
           << pose.translation.z() << " 1 " << FrameName(stats, f.frame) << "\n";
    int index = 0;
    bool first = true;
    for (const auto& obs : f.tags) {
      const bool mapped = result.tags.count(obs.id) > 0;
      for (int k = 0; k < 4; ++k) {
        const long long point_id = mapped ? CornerPointId(obs.id, k) : -1;
        images << (first ? "" : " ") << obs.pixels[k].x() + 0.5 << " " << obs.pixels[k].y() + 0.5 << " " << point_id;
        first = false;
        if (mapped) tracks[point_id].emplace_back(image_id, index);
        ++index;
      }
    }
    if (auto it = feature_views.find(f.frame); it != feature_views.end()) {
      for (const auto& [pixel, point_id] : it->second) {
        images << (first ? "" : " ") << pixel.x() + 0.5 << " " << pixel.y() + 0.5 << " " << point_id;
        first = false;
        tracks[point_id].emplace_back(image_id, index++);
      }
    }
    images << "\n";
  }
  const auto corner_stats = ComputeCornerStats(result);
  std::ostringstream points;
  points << std::setprecision(17) << "# 3D point list with one line of data per point:\n"
         << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n";
  for (const auto& [id, tag] : result.tags) {
    const TagCorners corners = tag.CornersInWorld();
    for (int k = 0; k < 4; ++k) {
      const long long point_id = CornerPointId(id, k);
      auto it = corner_stats.find({id, k});
      points << point_id << " " << corners[k].x() << " " << corners[k].y() << " " << corners[k].z() << " "
             << (tag.known ? "40 90 255 " : "255 140 0 ") << (it == corner_stats.end() ? 0.0 : it->second.rms_px);
      for (const auto& [img, idx] : tracks[point_id]) points << " " << img << " " << idx;
      points << "\n";
    }
  }
  for (size_t i = 0; i < result.feature_points.size(); ++i) {
    const FeaturePoint& p = result.feature_points[i];
    const long long point_id = kFirstFeaturePointId + static_cast<long long>(i);
    points << point_id << " " << p.position.x() << " " << p.position.y() << " " << p.position.z() << " "
           << int{p.rgb[0]} << " " << int{p.rgb[1]} << " " << int{p.rgb[2]} << " " << p.reprojection_rms_px;
    for (const auto& [img, idx] : tracks[point_id]) points << " " << img << " " << idx;
    points << "\n";
  }
  if (Status s = WriteFileAtomically(dir / "cameras.txt", cameras.str()); !s) return s;
  if (Status s = WriteFileAtomically(dir / "images.txt", images.str()); !s) return s;
  return WriteFileAtomically(dir / "points3D.txt", points.str());
}

Status WriteTargetCovariance(const std::filesystem::path& path, const TagCovariance& cov) {
  std::ostringstream out;
  out << std::setprecision(17) << "tag_a,tag_b";
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) out << ",c" << r << c;
  }
  out << "\n";
  for (size_t a = 0; a < cov.ids.size(); ++a) {
    for (size_t b = a; b < cov.ids.size(); ++b) {
      out << cov.ids[a] << "," << cov.ids[b];
      for (int r = 0; r < 6; ++r) {
        for (int c = 0; c < 6; ++c) out << "," << cov.covariance(static_cast<Eigen::Index>(6 * a + r), static_cast<Eigen::Index>(6 * b + c));
      }
      out << "\n";
    }
  }
  return WriteFileAtomically(path, out.str());
}

Result<TagCovariance> ReadTargetCovariance(const std::filesystem::path& path) {
  auto text = ReadFileToString(path);
  if (!text) return text.error();
  std::istringstream in(*text);
  std::string line;
  std::vector<std::pair<std::pair<TagId, TagId>, std::vector<double>>> rows;
  std::map<TagId, int> index;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line_number == 1 || line.find_first_not_of(" \r\t") == std::string::npos) continue;
    const auto fields = SplitCsvLine(line);
    const std::string where = path.string() + ":" + std::to_string(line_number) + ": ";
    if (fields.size() != 38) return MakeError(where + "expected 38 fields, found " + std::to_string(fields.size()));
    long long a = 0, b = 0;
    if (!ParseInt64(fields[0], &a) || !ParseInt64(fields[1], &b)) return MakeError(where + "tag ids must be integers");
    std::vector<double> values(36);
    for (int i = 0; i < 36; ++i) {
      if (!ParseDouble(fields[2 + i], &values[i])) return MakeError(where + "field " + std::to_string(i + 3) + " is not a number");
    }
    index.emplace(static_cast<TagId>(a), 0);
    index.emplace(static_cast<TagId>(b), 0);
    rows.push_back({{static_cast<TagId>(a), static_cast<TagId>(b)}, std::move(values)});
  }
  TagCovariance cov;
  for (auto& [id, i] : index) {
    i = static_cast<int>(cov.ids.size());
    cov.ids.push_back(id);
  }
  const int n = 6 * static_cast<int>(cov.ids.size());
  cov.covariance = Eigen::MatrixXd::Zero(n, n);
  for (const auto& [ids, values] : rows) {
    const int a = index[ids.first], b = index[ids.second];
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) {
        cov.covariance(6 * a + r, 6 * b + c) = values[6 * r + c];
        cov.covariance(6 * b + c, 6 * a + r) = values[6 * r + c];
      }
    }
  }
  return cov;
}

Status WriteResults(const std::filesystem::path& out_dir, const ReconstructionResult& result, const RunStats& stats) {
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) return MakeError(out_dir.string() + ": cannot create the output folder (" + ec.message() + ")");
  if (Status s = WritePosesCsv(out_dir / "poses.csv", result.Poses()); !s) return s;
  if (Status s = WriteTargetsCsv(out_dir / "targets.csv", result.Targets()); !s) return s;
  if (Status s = WriteCloudPly(out_dir / "cloud.ply", result); !s) return s;
  if (Status s = WriteFeaturePointsCsv(out_dir / "features.csv", result.feature_points, kFirstFeaturePointId); !s) return s;
  if (Status s = WriteColmapModel(out_dir / "colmap", result, stats); !s) return s;
  if (result.covariance) {
    if (Status s = WriteTargetCovariance(out_dir / "targets_cov.csv", *result.covariance); !s) return s;
  } else {
    std::filesystem::remove(out_dir / "targets_cov.csv", ec);
  }
  if (Status s = WritePreview(out_dir / "preview.png", result); !s) return s;
  return WriteReport(out_dir / "report.json", result, stats);
}

}  // namespace tagsfm
