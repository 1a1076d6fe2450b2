#include "tagsfm/feature/feature_map.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <unordered_map>

#include <opencv2/imgproc.hpp>

#include "tagsfm/feature/track_refinement.h"
#include "parallel_for.h"

namespace tagsfm {

Status FeatureMapOptions::Check() const {
  if (Status s = matcher.Check(); !s) return s;
  if (Status s = triangulation.Check(); !s) return s;
  if (Status s = refinement.Check(); !s) return s;
  if (!(refined_feature_sigma_px > 0)) return MakeError("feature_map.refined_feature_sigma_px must be > 0");
  if (max_neighbours < 1) return MakeError("feature_map.max_neighbours must be >= 1");
  if (!(min_overlap >= 0 && min_overlap <= 1)) return MakeError("feature_map.min_overlap must be in [0, 1]");
  if (!(max_view_angle_deg > 0 && max_view_angle_deg <= 180)) return MakeError("feature_map.max_view_angle_deg must be in (0, 180]");
  if (!(rematch_shift_px >= 0)) return MakeError("feature_map.rematch_shift_px must be >= 0");
  if (!(max_fit_sigma_per_epipolar_sigma >= 0)) return MakeError("feature_map.max_fit_sigma_per_epipolar_sigma must be >= 0");
  if (!(first_pass_max_reprojection_rms_px > 0)) {
    return MakeError("feature_map.first_pass_max_reprojection_rms_px must be > 0");
  }
  return Status::Ok();
}

FeatureMap::FeatureMap(const CameraModel& camera, const FeatureMapOptions& options) : camera_(camera), options_(options) {
  // A 9 x 6 grid of rays over the image, for the view overlap.
  std::vector<Eigen::Vector2d> pixels;
  constexpr int kCols = 9, kRows = 6;
  for (int r = 0; r < kRows; ++r) {
    for (int c = 0; c < kCols; ++c) pixels.emplace_back((c + 0.5) * camera.width / kCols - 0.5, (r + 0.5) * camera.height / kRows - 0.5);
  }
  for (const Eigen::Vector2d& n : camera.PixelsToNormalized(pixels)) view_sample_rays_.push_back(n.homogeneous());
}

Result<FeatureMap> FeatureMap::Create(const CameraModel& camera, const FeatureMapOptions& options) {
  if (Status s = camera.Check(); !s) return s.error();
  if (Status s = options.Check(); !s) return s.error();
  return FeatureMap(camera, options);
}

namespace {

// Share of `from`'s view (its sample rays at its typical depth) inside
// `to`'s image, and the angle between the two cameras' rays to the
// overlapping part (its centroid).
struct Overlap {
  double share = 0;
  double angle_deg = 180;
};

Overlap ViewOverlap(const PosedKeyframe& from, const PosedKeyframe& to, const std::vector<Eigen::Vector3d>& rays,
                    const CameraModel& camera) {
  const Rigid3d world_from_cam = from.cam_from_world.Inverse();
  const double depth = from.depth.Typical();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  int inside = 0;
  for (const Eigen::Vector3d& ray : rays) {
    const Eigen::Vector3d x = world_from_cam * (ray * depth);
    const Eigen::Vector3d in_to = to.cam_from_world * x;
    if (!(in_to.z() > 0)) continue;
    const Eigen::Vector2d p = camera.Project(in_to);
    if (p.x() < -0.5 || p.y() < -0.5 || p.x() > camera.width - 0.5 || p.y() > camera.height - 0.5) continue;
    centroid += x;
    ++inside;
  }
  Overlap o;
  if (inside == 0) return o;
  centroid /= inside;
  o.share = double(inside) / static_cast<double>(rays.size());
  const Eigen::Vector3d a = (centroid - from.cam_from_world.Center()).normalized();
  const Eigen::Vector3d b = (centroid - to.cam_from_world.Center()).normalized();
  o.angle_deg = std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180.0 / M_PI;
  return o;
}

// Each keyframe's image halved level by level (cv::pyrDown: pixel i of a
// level is pixel 2 i of the one below), for the fits across a change of
// scale; none when every fit is on the full images.
std::vector<std::vector<cv::Mat>> CoarseLevels(const std::vector<PosedKeyframe>& keyframes,
                                               const PatchRefinementOptions& options, int threads) {
  std::vector<std::vector<cv::Mat>> levels(keyframes.size());
  if (!options.balance_scale) return levels;
  ParallelFor(keyframes.size(), threads, [&](size_t k) {
    const cv::Mat* below = &keyframes[k].features.image;
    levels[k].reserve(static_cast<size_t>(options.max_level));
    for (int level = 1; level <= options.max_level && below->cols >= 16 && below->rows >= 16; ++level) {
      levels[k].emplace_back();
      cv::pyrDown(*below, levels[k].back());
      below = &levels[k].back();
    }
  });
  return levels;
}

// The epipolar lines' error across themselves, px, from the free fits'
// distances across them (1.4826 times the median absolute distance: a
// standard deviation that the few wrong fits do not inflate); 0 when there
// are too few fits to tell.
double EpipolarSigmaPx(const std::vector<TrackRefinementReport>& reports) {
  constexpr size_t kMinFits = 30;
  std::vector<double> distances;
  for (const TrackRefinementReport& report : reports) {
    for (const double across : report.across_epipolar_px) distances.push_back(std::abs(across));
  }
  if (distances.size() < kMinFits) return 0.0;
  const auto middle = distances.begin() + static_cast<std::ptrdiff_t>(distances.size() / 2);
  std::nth_element(distances.begin(), middle, distances.end());
  return 1.4826 * *middle;
}

}  // namespace

std::vector<int> FeatureMap::OverlappingKeyframes(const PosedKeyframe& added, int earlier_count) const {
  struct Candidate {
    int index;
    double share;
    double distance;
  };
  std::vector<Candidate> candidates;
  for (size_t k = 0; k < static_cast<size_t>(earlier_count); ++k) {
    const PosedKeyframe& earlier = keyframes_[k];
    // Both ways: each view's scene must be in the other's image.
    const Overlap a = ViewOverlap(added, earlier, view_sample_rays_, camera_);
    const Overlap b = ViewOverlap(earlier, added, view_sample_rays_, camera_);
    const double share = std::min(a.share, b.share);
    if (share <= 0 || share < options_.min_overlap) continue;
    if (std::max(a.angle_deg, b.angle_deg) > options_.max_view_angle_deg) continue;
    candidates.push_back({static_cast<int>(k), share, (added.cam_from_world.Center() - earlier.cam_from_world.Center()).norm()});
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    if (x.share != y.share) return x.share > y.share;
    return x.distance < y.distance;
  });
  if (static_cast<int>(candidates.size()) > options_.max_neighbours) candidates.resize(static_cast<size_t>(options_.max_neighbours));
  std::vector<int> out;
  for (const Candidate& c : candidates) out.push_back(c.index);
  return out;
}

int FeatureMap::Find(int node) const {
  while (parent_[static_cast<size_t>(node)] != node) {
    int& p = parent_[static_cast<size_t>(node)];
    p = parent_[static_cast<size_t>(p)];  // path halving
    node = p;
  }
  return node;
}

std::vector<int> FeatureMap::Members(int root) const {
  const std::vector<int>& m = members_[static_cast<size_t>(root)];
  return m.empty() ? std::vector<int>{root} : m;
}

bool FeatureMap::Union(int a, int b) {
  int ra = Find(a), rb = Find(b);
  if (ra == rb) return true;
  std::vector<int> ma = Members(ra), mb = Members(rb);
  if (ma.size() > mb.size()) {
    std::swap(ra, rb);
    std::swap(ma, mb);
  }
  // A track holds at most one feature per keyframe; tracks are short, so
  // the pairwise check is cheap.
  for (int x : ma) {
    for (int y : mb) {
      if (node_keyframe_[static_cast<size_t>(x)] == node_keyframe_[static_cast<size_t>(y)]) return false;
    }
  }
  parent_[static_cast<size_t>(ra)] = rb;
  mb.insert(mb.end(), ma.begin(), ma.end());
  members_[static_cast<size_t>(rb)] = std::move(mb);
  members_[static_cast<size_t>(ra)].clear();
  members_[static_cast<size_t>(ra)].shrink_to_fit();
  return true;
}

Result<KeyframeMatchStats> FeatureMap::AddKeyframe(KeyframeFeatures features, const Rigid3d& cam_from_world,
                                                   const DepthRange& depth, int threads) {
  for (const PosedKeyframe& k : keyframes_) {
    if (k.features.frame == features.frame) return MakeError("frame " + std::to_string(features.frame) + ": already a keyframe of the feature map");
  }
  auto posed = MakePosedKeyframe(std::move(features), cam_from_world, depth, camera_);
  if (!posed) return posed.error();
  keyframes_.push_back(std::move(*posed));
  return MatchLastKeyframe(nullptr, threads);
}

KeyframeMatchStats FeatureMap::MatchLastKeyframe(KeptMatches* kept, int threads) {
  const int index = static_cast<int>(keyframes_.size()) - 1;
  const PosedKeyframe& added = keyframes_.back();
  KeyframeMatchStats stats;
  stats.frame = added.features.frame;
  const std::vector<int> neighbours = OverlappingKeyframes(added, index);

  const int first = static_cast<int>(parent_.size());
  const int n = added.features.size();
  first_node_.push_back(first);
  for (int i = 0; i < n; ++i) {
    parent_.push_back(first + i);
    node_keyframe_.push_back(index);
  }
  members_.resize(parent_.size());
  pair_matches_.emplace_back();

  // The pairs are matched on `threads` threads (those Rematch keeps are
  // taken as they are), then merged in neighbour order: the tracks are the
  // same for any number of threads.
  std::vector<std::vector<FeatureMatch>> matches(neighbours.size());
  std::vector<size_t> to_match;
  for (size_t n = 0; n < neighbours.size(); ++n) {
    const FrameId earlier = keyframes_[static_cast<size_t>(neighbours[n])].features.frame;
    const auto reused = kept ? kept->find({added.features.frame, earlier}) : KeptMatches::iterator();
    if (kept && reused != kept->end()) {
      matches[n] = std::move(reused->second);
      ++stats.pairs_reused;
    } else {
      to_match.push_back(n);
    }
  }
  ParallelFor(
      to_match.size(), threads,
      [&](size_t m) {
        const size_t n = to_match[m];
        matches[n] = MatchGuided(added, keyframes_[static_cast<size_t>(neighbours[n])], camera_, options_.matcher).matches;
      },
      1);
  for (size_t n = 0; n < neighbours.size(); ++n) {
    const int k = neighbours[n];
    stats.matched_with.push_back(keyframes_[static_cast<size_t>(k)].features.frame);
    stats.matches += static_cast<int>(matches[n].size());
    MergeMatches(first, k, matches[n], &stats);
    pair_matches_.back().emplace_back(k, std::move(matches[n]));
  }
  return stats;
}

void FeatureMap::MergeMatches(int first_new, int earlier, const std::vector<FeatureMatch>& matches,
                              KeyframeMatchStats* stats) {
  for (const FeatureMatch& m : matches) {
    const int node_new = first_new + m.first, node_old = first_node_[static_cast<size_t>(earlier)] + m.second;
    const int root_new = Find(node_new), root_old = Find(node_old);
    if (root_new == root_old) continue;
    const size_t size_new = std::max<size_t>(1, members_[static_cast<size_t>(root_new)].size());
    const size_t size_old = std::max<size_t>(1, members_[static_cast<size_t>(root_old)].size());
    if (!Union(node_new, node_old)) {
      ++stats->conflicts;
      continue;
    }
    if (size_new == 1) {
      ++(size_old >= 2 ? stats->tracks_continued : stats->tracks_started);
    } else if (size_old >= 2) {
      ++stats->tracks_merged;
    }
  }
}

double FeatureMap::PairShiftPx(const PosedKeyframe& a, const PosedKeyframe& b, const Rigid3d& final_a,
                               const Rigid3d& final_b, const FeatureMap& final_map) const {
  // Only the relative pose places the epipolar band: a shift of the whole
  // world (the gauge) moves nothing, and a shift along the epipolar line
  // keeps a match inside the band; the shift across it is what counts.
  const Rigid3d live_b_from_a = b.cam_from_world * a.cam_from_world.Inverse();
  const Rigid3d final_b_from_a = final_b * final_a.Inverse();
  const double depth = a.depth.Typical();
  const CameraModel& final_camera = final_map.camera_;
  double shift = 0;
  for (size_t r = 0; r < view_sample_rays_.size(); ++r) {
    const Eigen::Vector3d ray = final_map.view_sample_rays_[r];
    const Eigen::Vector3d live = live_b_from_a * (view_sample_rays_[r] * depth);
    const Eigen::Vector3d now = final_b_from_a * (ray * depth);
    if (!(live.z() > 0) || !(now.z() > 0)) continue;  // behind b either way: matched in no band
    Eigen::Vector2d moved = final_camera.Project(now) - camera_.Project(live);
    const Eigen::Vector3d nearer = final_b_from_a * (ray * depth / 1.05), farther = final_b_from_a * (ray * depth * 1.05);
    if (nearer.z() > 0 && farther.z() > 0) {
      const Eigen::Vector2d line = final_camera.Project(farther) - final_camera.Project(nearer);
      if (line.norm() > 1e-3) moved -= moved.dot(line.normalized()) * line.normalized();
    }
    shift = std::max(shift, moved.norm());
  }
  return shift;
}

Result<int> FeatureMap::Rematch(const PoseMap& cam_from_world, const CameraModel& camera, int threads) {
  if (Status s = camera.Check(); !s) return s.error();
  FeatureMap next(camera, options_);
  // The pairs whose relative geometry the final poses and camera leave in
  // place keep their matches; the keyframes of the others are matched again.
  KeptMatches kept;
  for (size_t i = 0; i < keyframes_.size(); ++i) {
    const PosedKeyframe& a = keyframes_[i];
    const auto pose_a = cam_from_world.find(a.features.frame);
    for (auto& [k, matches] : pair_matches_[i]) {
      const PosedKeyframe& b = keyframes_[static_cast<size_t>(k)];
      const auto pose_b = cam_from_world.find(b.features.frame);
      if (pose_a == cam_from_world.end() || pose_b == cam_from_world.end()) continue;
      if (PairShiftPx(a, b, pose_a->second, pose_b->second, next) <= options_.rematch_shift_px) {
        kept[{a.features.frame, b.features.frame}] = std::move(matches);
      }
    }
  }
  std::vector<PosedKeyframe> old = std::move(keyframes_);
  *this = std::move(next);
  int rematched = 0;
  for (PosedKeyframe& keyframe : old) {
    const auto pose = cam_from_world.find(keyframe.features.frame);
    if (pose == cam_from_world.end()) continue;
    // The features passed MakePosedKeyframe's checks once; only the pose and
    // the undistortion change.
    auto posed = MakePosedKeyframe(std::move(keyframe.features), pose->second, keyframe.depth, camera_);
    if (!posed) return posed.error();
    keyframes_.push_back(std::move(*posed));
    const KeyframeMatchStats stats = MatchLastKeyframe(&kept, threads);
    rematched += static_cast<int>(stats.matched_with.size()) > stats.pairs_reused;
  }
  return rematched;
}

std::vector<FeatureTrack> FeatureMap::Tracks() const {
  std::vector<FeatureTrack> tracks;
  for (size_t root = 0; root < parent_.size(); ++root) {
    if (parent_[root] != static_cast<int>(root) || members_[root].size() < 2) continue;
    std::vector<int> nodes = members_[root];
    std::sort(nodes.begin(), nodes.end());
    FeatureTrack track;
    track.id = nodes.front();
    for (int node : nodes) {
      const int k = node_keyframe_[static_cast<size_t>(node)];
      const PosedKeyframe& kf = keyframes_[static_cast<size_t>(k)];
      const int feature = node - first_node_[static_cast<size_t>(k)];
      track.observations.push_back({kf.features.frame, feature, kf.features.pixels[static_cast<size_t>(feature)],
                                    kf.features.rgb[static_cast<size_t>(feature)]});
    }
    tracks.push_back(std::move(track));
  }
  std::sort(tracks.begin(), tracks.end(), [](const FeatureTrack& a, const FeatureTrack& b) { return a.id < b.id; });
  return tracks;
}

std::vector<FeaturePoint> FeatureMap::TriangulateCoarse(const PoseMap& cam_from_world, const CameraModel& camera) const {
  return TriangulateTracks(Tracks(), cam_from_world, camera, options_.triangulation);
}

std::vector<FeaturePoint> FeatureMap::Triangulate(const PoseMap& cam_from_world, const CameraModel& camera, int threads,
                                                  FeatureTriangulationStats* stats) const {
  FeatureTriangulationStats counts;
  std::vector<FeatureTrack> tracks = Tracks();
  if (!options_.refine) {
    std::vector<FeaturePoint> points =
        TriangulateTracks(tracks, cam_from_world, camera, options_.triangulation, threads, &counts.final_pass);
    if (stats != nullptr) *stats = counts;
    return points;
  }
  // The first points only predict the warps: no sigma filter, SIFT's noise,
  // any track within the fits' reach.
  TrackTriangulationOptions first_pass = options_.triangulation;
  first_pass.max_relative_sigma = 1.0;
  first_pass.max_reprojection_rms_px = options_.first_pass_max_reprojection_rms_px;
  const std::vector<FeaturePoint> first =
      TriangulateTracks(tracks, cam_from_world, camera, first_pass, threads, &counts.first_pass);
  const std::vector<std::vector<cv::Mat>> pyramids = CoarseLevels(keyframes_, options_.refinement, threads);
  std::unordered_map<FrameId, size_t> index_of;
  for (size_t k = 0; k < keyframes_.size(); ++k) index_of[keyframes_[k].features.frame] = k;
  const KeyframeImageLookup image_of = [&](FrameId frame, int level) -> const cv::Mat* {
    const auto it = index_of.find(frame);
    if (it == index_of.end()) return nullptr;
    if (level == 0) return &keyframes_[it->second].features.image;
    const std::vector<cv::Mat>& coarse = pyramids[it->second];
    return level <= static_cast<int>(coarse.size()) ? &coarse[static_cast<size_t>(level - 1)] : nullptr;
  };
  // Both sorted by track id; every point has its track.
  std::vector<size_t> track_of(first.size());
  for (size_t i = 0, t = 0; i < first.size(); ++i) {
    while (tracks[t].id != first[i].track) ++t;
    track_of[i] = t;
  }
  const double unrefined_sigma_px = options_.keep_unrefined_views ? options_.triangulation.feature_sigma_px : 0.0;
  PatchRefinementOptions refinement = options_.refinement;
  const auto refine = [&](size_t i, double epipolar_sigma_px, TrackRefinementReport* report) {
    return RefineTrackViews(tracks[track_of[i]], first[i], cam_from_world, image_of, camera, refinement,
                            unrefined_sigma_px, epipolar_sigma_px, report);
  };
  // The epipolar lines' error, from the free fits of every k-th track
  // (about kEpipolarSampleTracks of them: its median to a few per cent).
  if (options_.epipolar_fallback && !first.empty()) {
    constexpr size_t kEpipolarSampleTracks = 2000;
    const size_t stride = std::max<size_t>(1, first.size() / kEpipolarSampleTracks);
    std::vector<TrackRefinementReport> sample((first.size() + stride - 1) / stride);
    ParallelFor(sample.size(), threads, [&](size_t k) { refine(k * stride, 0.0, &sample[k]); });
    counts.epipolar_sigma_px = EpipolarSigmaPx(sample);
    refinement.max_sigma_px =
        std::max(refinement.max_sigma_px, options_.max_fit_sigma_per_epipolar_sigma * counts.epipolar_sigma_px);
    counts.max_fit_sigma_px = refinement.max_sigma_px;
  }
  std::vector<FeatureTrack> refined(first.size());
  std::vector<TrackRefinementReport> reports(first.size());
  ParallelFor(first.size(), threads, [&](size_t i) { refined[i] = refine(i, counts.epipolar_sigma_px, &reports[i]); });
  for (const TrackRefinementReport& report : reports) {
    counts.line_fits += report.line_fits;
    counts.tilted_fits += report.tilted_fits;
  }
  refined.erase(std::remove_if(refined.begin(), refined.end(), [](const FeatureTrack& r) { return r.observations.empty(); }),
                refined.end());
  counts.refinement_dropped = static_cast<int>(first.size() - refined.size());
  TrackTriangulationOptions final_pass = options_.triangulation;
  final_pass.feature_sigma_px = options_.refined_feature_sigma_px;
  final_pass.covariance_floor_px = counts.max_fit_sigma_px;
  std::vector<FeaturePoint> points =
      TriangulateTracks(refined, cam_from_world, camera, final_pass, threads, &counts.final_pass);
  if (stats != nullptr) *stats = counts;
  return points;
}

}  // namespace tagsfm
