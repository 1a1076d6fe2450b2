#include "tagsfm/recon/bundle_adjuster.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <memory>

#include <ceres/ceres.h>

#include "adjustment_covariance.h"
#include "tagsfm/recon/cost_functions.h"
#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm {
namespace {

ceres::Problem::Options ProblemOptions() {
  ceres::Problem::Options options;
  // Slow removal scans the residual blocks in the problem's order; fast
  // removal walks a hash set of pointers, whose order changes from run to
  // run, and with it the order of the sums (the same recording gave poses
  // 1e-17 m apart, which the feature refinement amplified to 1e-6 m). The
  // window is small: the scan costs nothing measurable.
  options.enable_fast_removal = false;
  options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return options;
}

ceres::HuberLoss* SharedLoss(double huber_px) {
  // One loss object per scale, shared by every residual (the problems do not own it).
  static thread_local std::map<double, std::unique_ptr<ceres::HuberLoss>> losses;
  auto& loss = losses[huber_px];
  if (!loss) loss = std::make_unique<ceres::HuberLoss>(huber_px);
  return loss.get();
}

ceres::Manifold* SharedPoseManifold() {
  static PoseManifold manifold;
  return &manifold;
}

void AddPoseBlock(ceres::Problem* problem, PoseParams* pose) {
  problem->AddParameterBlock(pose->data, 7, SharedPoseManifold());
}

const std::array<Eigen::Matrix2d, 4> kEqualWeights = {Eigen::Matrix2d::Identity(), Eigen::Matrix2d::Identity(),
                                                     Eigen::Matrix2d::Identity(), Eigen::Matrix2d::Identity()};

// Adds the residual blocks of one observation; returns how many.
// `world_from_tag`: the learned tag's parameter block (unused for a known tag).
// `weighted`: each corner whitened by the observation's weights (the edge
// fit's covariance), else every corner counts the same.
int AddTagResiduals(ceres::Problem* problem, PoseParams* cam_from_world, const TagObservation& obs, const MapTag& tag,
                    PoseParams* world_from_tag, double fx, double fy, double huber_px, bool weighted) {
  const std::array<Eigen::Matrix2d, 4>& weights = weighted ? obs.weight_undistorted : kEqualWeights;
  ceres::LossFunction* loss = SharedLoss(huber_px);
  // A whole tag's block holds four corners: its squared error is ~4 times a
  // corner's, so its robust scale is twice a corner's.
  ceres::LossFunction* tag_loss = SharedLoss(2 * huber_px);
  if (tag.known) {
    for (int k = 0; k < 4; ++k) {
      problem->AddResidualBlock(
          FixedPointReprojectionError::Create(obs.normalized[k], tag.known_corners[k], fx, fy, weights[k]),
          loss, cam_from_world->data);
    }
    return 4;
  }
  problem->AddResidualBlock(TagReprojectionError::Create(obs.normalized, tag.size_m, fx, fy, weights),
                            tag_loss, cam_from_world->data, world_from_tag->data);
  return 1;
}

// Each point's observations as residuals on the frames' poses (added where
// a frame has none yet), through `intrinsics` when they are adjusted (else
// null); returns how many point blocks went in.
int AddPointResiduals(ceres::Problem* problem, const std::vector<FrameState*>& frames, const PointTerms& terms,
                      double fx, double fy, double* intrinsics) {
  std::map<FrameId, FrameState*> by_id;
  for (FrameState* frame : frames) {
    if (frame->registered) by_id[frame->frame] = frame;
  }
  ceres::LossFunction* loss = SharedLoss(terms.weight * terms.huber_px);
  int added = 0;
  for (AdjustedPoint& point : *terms.points) {
    int views = 0;
    for (const auto& [frame, pixel] : point.observations) {
      auto it = by_id.find(frame);
      if (it == by_id.end()) continue;
      PoseParams* pose = &it->second->cam_from_world;
      if (!problem->HasParameterBlock(pose->data)) AddPoseBlock(problem, pose);
      if (views == 0) problem->AddParameterBlock(point.position.data(), 3);
      if (intrinsics) {
        problem->AddResidualBlock(PointPixelReprojectionError::Create(pixel, terms.weight), loss, pose->data,
                                  point.position.data(), intrinsics);
      } else {
        const Eigen::Vector2d normalized = terms.camera->PixelToNormalized(pixel);
        problem->AddResidualBlock(ReprojectionError::Create(normalized, terms.weight * fx, terms.weight * fy), loss,
                                  pose->data, point.position.data());
      }
      ++views;
    }
    added += views > 0;
  }
  return added;
}

}  // namespace

Status BundleAdjusterOptions::Check() const {
  if (window_keyframes < 2) return MakeError("ba.window_keyframes must be >= 2");
  if (window_iterations < 1) return MakeError("ba.window_iterations must be >= 1");
  if (global_iterations < 1) return MakeError("ba.global_iterations must be >= 1");
  if (!(huber_px > 0)) return MakeError("ba.huber_px must be > 0");
  if (global_threads < 1) return MakeError("ba.global_threads must be >= 1");
  if (window_threads < 1) return MakeError("ba.window_threads must be >= 1");
  return Status::Ok();
}

SlidingWindowBundleAdjuster::SlidingWindowBundleAdjuster(const BundleAdjusterOptions& options, double fx, double fy)
    : options_(options), fx_(fx), fy_(fy), problem_(std::make_unique<ceres::Problem>(ProblemOptions())) {}

SlidingWindowBundleAdjuster::~SlidingWindowBundleAdjuster() = default;

size_t SlidingWindowBundleAdjuster::residual_blocks() const { return static_cast<size_t>(problem_->NumResidualBlocks()); }

void SlidingWindowBundleAdjuster::AddObservation(Keyframe* keyframe, const TagObservation& obs, const MapTag& tag) {
  MapTag* learned = nullptr;
  if (!tag.known) {
    auto [it, inserted] = learned_tags_.emplace(tag.id, tag);
    learned = &it->second;
    if (inserted) {
      AddPoseBlock(problem_.get(), &learned->world_from_tag);
      if (tag.anchor) problem_->SetParameterBlockConstant(learned->world_from_tag.data);
    }
  }
  // Unweighted: the live survey's decisions (which tags to map, which
  // views are outliers) are taken on equal votes (BundleAdjusterOptions).
  AddTagResiduals(problem_.get(), &keyframe->cam_from_world, obs, tag, learned ? &learned->world_from_tag : nullptr,
                  fx_, fy_, options_.huber_px, /*weighted=*/false);
  ++residuals_per_tag_[tag.id];  // views of the tag in the window
  keyframe->in_problem.push_back(tag.id);
}

void SlidingWindowBundleAdjuster::AddKeyframe(const FrameState& frame, const std::map<TagId, MapTag>& tags) {
  if (window_.size() >= static_cast<size_t>(options_.window_keyframes)) RemoveOldest();
  Keyframe& keyframe = window_.emplace_back();
  keyframe.frame = frame.frame;
  keyframe.cam_from_world = frame.cam_from_world;
  keyframe.views = frame.tags;
  AddPoseBlock(problem_.get(), &keyframe.cam_from_world);
  for (const auto& obs : keyframe.views) {
    auto it = tags.find(obs.id);
    if (it == tags.end() || obs.outlier) continue;
    // A tag already in the window is adjusted there: the window's copy is the newer.
    auto in_window = learned_tags_.find(obs.id);
    AddObservation(&keyframe, obs, in_window != learned_tags_.end() ? in_window->second : it->second);
  }
  HoldOldestFixed();
}

void SlidingWindowBundleAdjuster::AddTag(const MapTag& tag) {
  for (Keyframe& keyframe : window_) {
    for (const TagObservation& obs : keyframe.views) {
      if (obs.id == tag.id && !obs.outlier) AddObservation(&keyframe, obs, tag);
    }
  }
}

std::vector<FrameId> SlidingWindowBundleAdjuster::ReplaceTag(const MapTag& tag, const std::vector<FrameId>& fitted) {
  auto learned = learned_tags_.find(tag.id);
  if (learned != learned_tags_.end()) {
    problem_->RemoveParameterBlock(learned->second.world_from_tag.data);  // and its residuals
    learned_tags_.erase(learned);
  }
  residuals_per_tag_.erase(tag.id);
  std::vector<FrameId> outliers;
  for (Keyframe& keyframe : window_) {
    auto& ids = keyframe.in_problem;
    ids.erase(std::remove(ids.begin(), ids.end(), tag.id), ids.end());
    for (TagObservation& obs : keyframe.views) {
      if (obs.id != tag.id) continue;
      obs.outlier = std::find(fitted.begin(), fitted.end(), keyframe.frame) == fitted.end();
      if (obs.outlier) {
        outliers.push_back(keyframe.frame);
      } else {
        AddObservation(&keyframe, obs, tag);
      }
    }
  }
  return outliers;
}

void SlidingWindowBundleAdjuster::RemoveOldest() {
  Keyframe& oldest = window_.front();
  // Removing the pose block removes the frame's residuals with it.
  problem_->RemoveParameterBlock(oldest.cam_from_world.data);
  for (TagId id : oldest.in_problem) {
    if (--residuals_per_tag_[id] > 0) continue;
    residuals_per_tag_.erase(id);
    auto it = learned_tags_.find(id);
    if (it != learned_tags_.end()) {
      problem_->RemoveParameterBlock(it->second.world_from_tag.data);
      learned_tags_.erase(it);
    }
  }
  window_.pop_front();
}

void SlidingWindowBundleAdjuster::HoldOldestFixed() {
  // The oldest keyframe stands in for everything that left the window: held
  // fixed, it keeps the window from drifting (and fixes the gauge).
  if (!window_.empty()) problem_->SetParameterBlockConstant(window_.front().cam_from_world.data);
}

WindowSolution SlidingWindowBundleAdjuster::Solve() {
  WindowSolution solution;
  bool any_free = false;
  for (const auto& [id, tag] : learned_tags_) any_free = any_free || !tag.anchor;
  if (!any_free || window_.size() < 2) return solution;
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_SCHUR;
  options.max_num_iterations = options_.window_iterations;
  options.num_threads = options_.window_threads;
  options.logging_type = ceres::SILENT;
  // Ceres writes into the blocks as it goes: a solve that fails must not
  // leave the window's poses and tags where it gave up.
  std::vector<PoseParams> poses;
  for (const Keyframe& keyframe : window_) poses.push_back(keyframe.cam_from_world);
  std::map<TagId, PoseParams> tags;
  for (const auto& [id, tag] : learned_tags_) tags[id] = tag.world_from_tag;
  ceres::Solver::Summary summary;
  ceres::Solve(options, problem_.get(), &summary);
  bool usable = summary.IsSolutionUsable();
  for (const Keyframe& keyframe : window_) usable = usable && keyframe.cam_from_world.ToRigid().translation.allFinite();
  if (!usable) {
    for (size_t i = 0; i < window_.size(); ++i) window_[i].cam_from_world = poses[i];
    for (auto& [id, tag] : learned_tags_) tag.world_from_tag = tags[id];
    ++failed_solves_;
    return solution;
  }
  solution.solved = true;
  for (const Keyframe& keyframe : window_) solution.cam_from_world.emplace_back(keyframe.frame, keyframe.cam_from_world);
  for (const auto& [id, tag] : learned_tags_) {
    if (!tag.anchor) solution.world_from_tag.emplace_back(id, tag.world_from_tag);
  }
  return solution;
}

namespace {

double RmsOf(ceres::Problem* problem) {
  double cost = 0;
  ceres::Problem::EvaluateOptions eval;
  eval.apply_loss_function = false;
  std::vector<double> residuals;
  problem->Evaluate(eval, &cost, &residuals, nullptr, nullptr);
  return residuals.empty() ? 0.0 : std::sqrt(2.0 * cost / (static_cast<double>(residuals.size()) / 2.0));
}

// The feature points eliminated first and alone: every eliminated block is
// then a 3-vector seen only by 2-row residuals on a 6-dof pose, which Ceres'
// Schur eliminator has compiled for (its automatic ordering also eliminated
// the learned tags, and fell back to dynamic block sizes). Ceres orders a
// group's blocks by address, and heap addresses vary from run to run with
// the threads' allocations, so every other block gets a group of its own,
// in frame order, tag id order, then the camera: the same arithmetic in
// every run. Their reduced system is small and dense, so the fixed order
// costs no fill.
std::shared_ptr<ceres::ParameterBlockOrdering> PointsFirstOrdering(const ceres::Problem& problem,
                                                                   std::vector<AdjustedPoint>& points,
                                                                   const std::vector<FrameState*>& frames,
                                                                   std::map<TagId, MapTag>& tags, double* intrinsics) {
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  // The points lie in one vector: their addresses follow their order.
  for (AdjustedPoint& point : points) {
    if (problem.HasParameterBlock(point.position.data())) ordering->AddElementToGroup(point.position.data(), 0);
  }
  int group = 1;
  auto add = [&](double* block) {
    if (problem.HasParameterBlock(block) && !ordering->IsMember(block)) ordering->AddElementToGroup(block, group++);
  };
  for (FrameState* frame : frames) add(frame->cam_from_world.data);
  for (auto& [id, tag] : tags) add(tag.world_from_tag.data);
  add(intrinsics);
  // A block of another kind would be left out: Ceres then orders them all.
  if (ordering->NumElements() != problem.NumParameterBlocks()) return nullptr;
  return ordering;
}

// The adjusted intrinsics' block: fx, fy, cx, cy, k1, k2 (cx.. zero when
// the intrinsics stay fixed: the block is then not in the problem).
std::array<double, 6> IntrinsicsBlock(double fx, double fy, const CameraModel* refine_camera) {
  std::array<double, 6> intrinsics{fx, fy, 0, 0, 0, 0};
  if (refine_camera) {
    const auto& d = refine_camera->distortion;
    intrinsics[2] = refine_camera->cx;
    intrinsics[3] = refine_camera->cy;
    intrinsics[4] = d.size() > 0 ? d[0] : 0.0;
    intrinsics[5] = d.size() > 1 ? d[1] : 0.0;
  }
  return intrinsics;
}

// The registered frames' tag observations as residuals, with each frame's
// pose and each learned tag's pose as blocks (the anchor held constant);
// through `intrinsics` when they are adjusted (else null). Returns the
// free parameters added.
int AddTargetResiduals(ceres::Problem* problem, const std::vector<FrameState*>& frames, std::map<TagId, MapTag>* tags,
                       double fx, double fy, double huber_px, bool weighted, double* intrinsics) {
  int free_parameters = 0;
  std::map<TagId, bool> added;
  for (FrameState* frame : frames) {
    if (!frame->registered) continue;
    int residuals = 0;
    for (const auto& obs : frame->tags) {
      auto it = tags->find(obs.id);
      if (it == tags->end() || obs.outlier) continue;
      MapTag& tag = it->second;
      if (!tag.known && !added[tag.id]) {
        AddPoseBlock(problem, &tag.world_from_tag);
        if (tag.anchor) {
          problem->SetParameterBlockConstant(tag.world_from_tag.data);
        } else {
          free_parameters += 6;
        }
        added[tag.id] = true;
      }
      if (residuals == 0) {
        AddPoseBlock(problem, &frame->cam_from_world);
        free_parameters += 6;
      }
      if (!intrinsics) {
        residuals += AddTagResiduals(problem, &frame->cam_from_world, obs, tag, &tag.world_from_tag, fx, fy, huber_px,
                                     weighted);
        continue;
      }
      const std::array<Eigen::Matrix2d, 4>& weights = weighted ? obs.weight_pixels : kEqualWeights;
      if (tag.known) {
        for (int k = 0; k < 4; ++k) {
          problem->AddResidualBlock(
              FixedPointPixelReprojectionError::Create(obs.pixels[k], tag.known_corners[k], weights[k]),
              SharedLoss(huber_px), frame->cam_from_world.data, intrinsics);
        }
      } else {
        problem->AddResidualBlock(TagPixelReprojectionError::Create(obs.pixels, tag.size_m, weights),
                                  SharedLoss(2 * huber_px), frame->cam_from_world.data, tag.world_from_tag.data,
                                  intrinsics);
      }
      ++residuals;
    }
  }
  return free_parameters;
}

ceres::Solver::Options GlobalSolverOptions(const BundleAdjusterOptions& options) {
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::SPARSE_SCHUR;
  solver.max_num_iterations = options.global_iterations;
  solver.num_threads = options.global_threads;
  solver.function_tolerance = 1e-12;
  solver.parameter_tolerance = 1e-12;
  solver.gradient_tolerance = 1e-14;
  solver.logging_type = ceres::SILENT;
  return solver;
}

void StoreIntrinsics(const std::array<double, 6>& intrinsics, CameraModel* camera) {
  camera->fx = intrinsics[0];
  camera->fy = intrinsics[1];
  camera->cx = intrinsics[2];
  camera->cy = intrinsics[3];
  camera->distortion = {intrinsics[4], intrinsics[5], 0.0, 0.0, 0.0};
}

}  // namespace

GlobalAdjustmentSummary AdjustGlobally(const std::vector<FrameState*>& frames, std::map<TagId, MapTag>* tags,
                                       double fx, double fy, const BundleAdjusterOptions& options,
                                       CameraModel* refine_camera, const PointTerms* points) {
  GlobalAdjustmentSummary out;
  ceres::Problem problem(ProblemOptions());
  std::array<double, 6> intrinsics = IntrinsicsBlock(fx, fy, refine_camera);
  double* adjusted_intrinsics = refine_camera ? intrinsics.data() : nullptr;
  int free_parameters = AddTargetResiduals(&problem, frames, tags, fx, fy, options.huber_px, options.weight_corners,
                                           adjusted_intrinsics);
  // The targets' residuals come first: their spread is the variance the covariance is scaled by.
  const int target_residuals = problem.NumResiduals();
  if (points && points->points) AddPointResiduals(&problem, frames, *points, fx, fy, adjusted_intrinsics);
  if (adjusted_intrinsics && options.square_pixels && problem.HasParameterBlock(adjusted_intrinsics)) {
    // 1e-3 px: a thousandth of any corner's noise, yet a normal matrix
    // entry of only 1e6, which the covariance's factorisation takes.
    intrinsics[0] = intrinsics[1] = 0.5 * (intrinsics[0] + intrinsics[1]);
    problem.AddResidualBlock(SquarePixelTie::Create(1e-3), nullptr, adjusted_intrinsics);
  }
  if (problem.NumResidualBlocks() == 0) {
    out.covariance_note = "nothing to adjust";
    return out;
  }
  out.initial_rms_px = RmsOf(&problem);
  ceres::Solver::Options solver = GlobalSolverOptions(options);
  if (points && points->points) {
    solver.linear_solver_ordering = PointsFirstOrdering(problem, *points->points, frames, *tags, intrinsics.data());
  }
  ceres::Solver::Summary summary;
  const auto t0 = std::chrono::steady_clock::now();
  ceres::Solve(solver, &problem, &summary);
  const auto t1 = std::chrono::steady_clock::now();
  out.solve_s = std::chrono::duration<double>(t1 - t0).count();
  out.converged = summary.termination_type == ceres::CONVERGENCE;
  out.iterations = static_cast<int>(summary.iterations.size());
  out.final_rms_px = RmsOf(&problem);
  if (refine_camera && summary.IsSolutionUsable()) {
    StoreIntrinsics(intrinsics, refine_camera);
    free_parameters += 6;
  }
  if (options.compute_covariance) {
    ComputeCovariance(&problem, frames, tags, adjusted_intrinsics, points ? points->points : nullptr, target_residuals,
                      free_parameters, &out);
  }
  out.covariance_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  return out;
}

std::map<TagId, std::array<double, 4>> RelaxedTagEdgeLengths(const std::vector<FrameState*>& frames,
                                                             const std::map<TagId, MapTag>& tags, double fx,
                                                             double fy, const BundleAdjusterOptions& options) {
  // Copies: the diagnostic leaves the reconstruction as it is.
  std::vector<PoseParams> cameras;
  cameras.reserve(frames.size());
  std::map<TagId, std::array<std::array<double, 3>, 4>> corners;
  for (const auto& [id, tag] : tags) {
    const TagCorners c = tag.CornersInWorld();
    for (int k = 0; k < 4; ++k) corners[id][k] = {c[k].x(), c[k].y(), c[k].z()};
  }
  ceres::Problem problem(ProblemOptions());
  ceres::LossFunction* loss = SharedLoss(options.huber_px);
  for (const FrameState* frame : frames) {
    if (!frame->registered) continue;
    cameras.push_back(frame->cam_from_world);
    PoseParams& cam = cameras.back();
    bool added = false;
    for (const auto& obs : frame->tags) {
      auto it = corners.find(obs.id);
      if (it == corners.end() || obs.outlier) continue;
      if (!added) {
        AddPoseBlock(&problem, &cam);
        added = true;
      }
      for (int k = 0; k < 4; ++k) {
        problem.AddResidualBlock(ReprojectionError::Create(obs.normalized[k], fx, fy), loss, cam.data, it->second[k].data());
      }
    }
  }
  std::map<TagId, std::array<double, 4>> out;
  for (auto& [id, c] : corners) {
    const MapTag& tag = tags.at(id);
    for (int k = 0; k < 4; ++k) {
      if (problem.HasParameterBlock(c[k].data()) && (tag.known || tag.anchor)) problem.SetParameterBlockConstant(c[k].data());
    }
  }
  if (problem.NumResidualBlocks() == 0) return out;
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::SPARSE_SCHUR;
  solver.max_num_iterations = options.global_iterations;
  solver.num_threads = options.global_threads;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  for (const auto& [id, c] : corners) {
    const MapTag& tag = tags.at(id);
    if (tag.known || tag.anchor || !problem.HasParameterBlock(c[0].data())) continue;
    TagCorners relaxed;
    for (int k = 0; k < 4; ++k) relaxed[k] = Eigen::Vector3d(c[k][0], c[k][1], c[k][2]);
    out[id] = TagEdgeLengths(relaxed);
  }
  return out;
}

}  // namespace tagsfm
