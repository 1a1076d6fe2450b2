#include "tagsfm/recon/pose_estimator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm {
namespace {

// Rotation and translation both finite: a solver's degenerate sample can
// give a NaN rotation with a finite translation.
bool IsFinite(const Rigid3d& pose) { return pose.rotation.coeffs().allFinite() && pose.translation.allFinite(); }

Rigid3d FromRvecTvec(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat rotation_cv;
  cv::Rodrigues(rvec, rotation_cv);
  Eigen::Matrix3d rotation;
  cv::cv2eigen(rotation_cv, rotation);
  return Rigid3d(Eigen::Quaterniond(rotation), Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
}

// Eigenvalues of the points' scatter, largest first.
Eigen::Vector3d Spread(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter / static_cast<double>(points.size()));
  const Eigen::Vector3d ev = solver.eigenvalues();  // ascending
  return {ev(2), ev(1), std::max(ev(0), 0.0)};
}

bool ImagePointsCollinear(const std::vector<Eigen::Vector2d>& normalized) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : normalized) mean += p;
  mean /= static_cast<double>(normalized.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& p : normalized) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(scatter);
  return solver.eigenvalues()(0) <= 1e-12 * std::max(solver.eigenvalues()(1), 1e-300);
}

struct Candidate {
  PoseMethod method = PoseMethod::kNone;
  Rigid3d cam_from_world;
  std::vector<int> inliers;
  double rms_px = 0;
  bool in_front = false;
  double inlier_ratio = 0;
  bool passes = false;
  double jump_deg = 0;
  std::string failure;
};

class CandidateEvaluator {
 public:
  CandidateEvaluator(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector2d>& normalized,
                     double fx, double fy, const std::optional<Rigid3d>& previous, const PoseEstimatorOptions& options)
      : points_(points), normalized_(normalized), fx_(fx), fy_(fy), previous_(previous), options_(options) {}

  // Refines `initial` on `use` (all points when empty), then re-selects the
  // inliers, refines again on them and checks the result.
  Candidate Evaluate(PoseMethod method, const Rigid3d& initial, std::vector<int> use) const {
    if (use.size() < 4) use = AllIndices();
    Candidate c;
    c.method = method;
    c.cam_from_world = RefinePose(points_, normalized_, use, fx_, fy_, initial, HuberPx(), options_.refine_iterations);
    c.inliers = Inliers(c.cam_from_world);
    if (c.inliers.size() >= 4 && c.inliers != use) {
      c.cam_from_world =
          RefinePose(points_, normalized_, c.inliers, fx_, fy_, c.cam_from_world, HuberPx(), options_.refine_iterations);
      c.inliers = Inliers(c.cam_from_world);
    }
    Check(&c);
    return c;
  }

  std::vector<int> AllIndices() const {
    std::vector<int> all(points_.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    return all;
  }

 private:
  Eigen::Vector2d ErrorPx(const Rigid3d& pose, int i, double* depth) const {
    const Eigen::Vector3d p = pose * points_[i];
    *depth = p.z();
    return {fx_ * (p.x() / p.z() - normalized_[i].x()), fy_ * (p.y() / p.z() - normalized_[i].y())};
  }

  // Corners in front of the camera within the inlier threshold, and within
  // outlier_sigmas robust sigmas of the pose's errors (see the options).
  std::vector<int> Inliers(const Rigid3d& pose) const {
    std::vector<double> errors(points_.size());
    std::vector<double> in_front;
    in_front.reserve(points_.size());
    for (size_t i = 0; i < points_.size(); ++i) {
      double depth = 0;
      errors[i] = ErrorPx(pose, static_cast<int>(i), &depth).norm();
      if (!(depth > 0)) errors[i] = INFINITY;
      if (errors[i] < InlierThresholdPx()) in_front.push_back(errors[i]);
    }
    double threshold = InlierThresholdPx();
    if (!in_front.empty()) {
      std::nth_element(in_front.begin(), in_front.begin() + in_front.size() / 2, in_front.end());
      // The median of a 2D Gaussian error's length is sigma * sqrt(2 ln 2).
      const double robust_sigma = in_front[in_front.size() / 2] / 1.1774;
      threshold = std::min(threshold, std::max(options_.min_outlier_px, options_.outlier_sigmas * robust_sigma));
    }
    std::vector<int> out;
    for (size_t i = 0; i < points_.size(); ++i) {
      if (errors[i] < threshold) out.push_back(static_cast<int>(i));
    }
    return out;
  }

  double InlierThresholdPx() const { return std::max(options_.ransac_threshold_px, 4.0 * options_.corner_sigma_px); }
  double MaxRmsPx() const {
    return std::max(options_.max_rms_px, options_.rms_sigmas * std::sqrt(2.0) * options_.corner_sigma_px);
  }
  double HuberPx() const { return std::max(options_.huber_px, 2.0 * options_.corner_sigma_px); }

  void Check(Candidate* c) const {
    double sum = 0;
    c->in_front = true;
    for (int i : c->inliers) {
      double depth = 0;
      sum += ErrorPx(c->cam_from_world, i, &depth).squaredNorm();
      if (!(depth > 0)) c->in_front = false;
    }
    // The points as a whole must lie in front too, not just the inliers.
    int behind = 0;
    for (const auto& p : points_) behind += (c->cam_from_world * p).z() <= 0;
    if (behind * 2 > static_cast<int>(points_.size())) c->in_front = false;
    c->rms_px = c->inliers.empty() ? INFINITY : std::sqrt(sum / static_cast<double>(c->inliers.size()));
    c->inlier_ratio = static_cast<double>(c->inliers.size()) / static_cast<double>(points_.size());
    c->jump_deg = previous_ ? RotationAngleDeg(previous_->rotation, c->cam_from_world.rotation) : 0.0;
    std::ostringstream why;
    if (c->inliers.size() < 4) {
      why << "only " << c->inliers.size() << " inlier corners";
    } else if (!c->in_front) {
      why << "no pose puts the points in front of the camera";
    } else if (!(c->rms_px <= MaxRmsPx())) {
      why << "reprojection RMS " << c->rms_px << " px > " << MaxRmsPx() << " px";
    } else if (c->inlier_ratio < options_.min_inlier_ratio) {
      why << "only " << c->inliers.size() << " of " << points_.size() << " corners agree";
    }
    c->failure = why.str();
    c->passes = c->failure.empty();
  }

  const std::vector<Eigen::Vector3d>& points_;
  const std::vector<Eigen::Vector2d>& normalized_;
  double fx_, fy_;
  const std::optional<Rigid3d>& previous_;
  const PoseEstimatorOptions& options_;
};

// Picks among the checked candidates: the lowest RMS, except that a candidate
// nearly as good which agrees with the previous frame beats one that jumped.
const Candidate* Choose(const std::vector<Candidate>& candidates, double max_jump_deg) {
  double best_rms = INFINITY;
  for (const auto& c : candidates) {
    if (c.passes) best_rms = std::min(best_rms, c.rms_px);
  }
  const Candidate* chosen = nullptr;
  for (const auto& c : candidates) {
    if (!c.passes || c.rms_px > 1.5 * best_rms + 0.05) continue;
    if (!chosen) {
      chosen = &c;
      continue;
    }
    const bool c_agrees = c.jump_deg <= max_jump_deg, chosen_agrees = chosen->jump_deg <= max_jump_deg;
    if (c_agrees != chosen_agrees) {
      if (c_agrees) chosen = &c;
    } else if (c.rms_px < chosen->rms_px - 1e-9) {
      chosen = &c;
    }
  }
  return chosen;
}

std::vector<cv::Point3d> ToCv(const std::vector<Eigen::Vector3d>& points, const std::vector<int>& use) {
  std::vector<cv::Point3d> out;
  out.reserve(use.size());
  for (int i : use) out.emplace_back(points[i].x(), points[i].y(), points[i].z());
  return out;
}
std::vector<cv::Point2d> ToCv(const std::vector<Eigen::Vector2d>& points, const std::vector<int>& use) {
  std::vector<cv::Point2d> out;
  out.reserve(use.size());
  for (int i : use) out.emplace_back(points[i].x(), points[i].y());
  return out;
}

}  // namespace

const char* PoseMethodName(PoseMethod method) {
  switch (method) {
    case PoseMethod::kEpnp: return "epnp";
    case PoseMethod::kSqpnp: return "sqpnp";
    case PoseMethod::kIppe: return "ippe";
    default: return "none";
  }
}

Status PoseEstimatorOptions::Check() const {
  if (!(ransac_threshold_px > 0)) return MakeError("pose.ransac_threshold_px must be > 0");
  if (ransac_iterations < 1) return MakeError("pose.ransac_iterations must be >= 1");
  if (!(ransac_confidence > 0 && ransac_confidence < 1)) return MakeError("pose.ransac_confidence must be in (0, 1)");
  if (!(max_rms_px > 0)) return MakeError("pose.max_rms_px must be > 0");
  if (!(corner_sigma_px >= 0)) return MakeError("pose.corner_sigma_px must be >= 0");
  if (!(rms_sigmas > 0)) return MakeError("pose.rms_sigmas must be > 0");
  if (!(outlier_sigmas > 0)) return MakeError("pose.outlier_sigmas must be > 0");
  if (!(min_outlier_px > 0)) return MakeError("pose.min_outlier_px must be > 0");
  if (!(min_inlier_ratio > 0 && min_inlier_ratio <= 1)) return MakeError("pose.min_inlier_ratio must be in (0, 1]");
  if (!(max_rotation_jump_deg > 0)) return MakeError("pose.max_rotation_jump_deg must be > 0");
  if (!(planarity_ratio >= 0 && planarity_ratio < 1)) return MakeError("pose.planarity_ratio must be in [0, 1)");
  if (!(huber_px > 0)) return MakeError("pose.huber_px must be > 0");
  if (refine_iterations < 1) return MakeError("pose.refine_iterations must be >= 1");
  return Status::Ok();
}

std::vector<Rigid3d> TagPoseCandidates(const std::array<Eigen::Vector2d, 4>& normalized, double size_m) {
  // IPPE is solved in the tag frame turned 180 degrees about x: a tag facing
  // the camera is then near the identity rotation. In the tag's own frame
  // such a tag sits at a 180 degree rotation, where OpenCV's Rodrigues
  // conversion is ill-conditioned: on exact data of a tag tilted 60 degrees,
  // both of OpenCV 4.6's IPPE solutions came back 80 and 118 degrees off,
  // while in the turned frame one was exact.
  const Eigen::Quaterniond turned_from_tag(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  std::vector<Eigen::Vector3d> corners_in_tag(4);
  const std::vector<Eigen::Vector2d> observed(normalized.begin(), normalized.end());
  const std::vector<int> all_four{0, 1, 2, 3};
  for (int k = 0; k < 4; ++k) {
    corners_in_tag[k] = TagCornerInTag(k, size_m);
    const Eigen::Vector3d turned = turned_from_tag * corners_in_tag[k];
    object.emplace_back(turned.x(), turned.y(), 0.0);
    image.emplace_back(normalized[k].x(), normalized[k].y());
  }
  std::vector<cv::Mat> rvecs, tvecs;
  try {
    cv::solvePnPGeneric(object, image, cv::Mat::eye(3, 3, CV_64F), cv::noArray(), rvecs, tvecs, false,
                        cv::SOLVEPNP_IPPE);
  } catch (const cv::Exception&) {
    return {};
  }
  // IPPE's solutions are first-order: unrefined, the wrong branch of a
  // nearly head-on tag was measured to reproject better on exact data (9.8e-5
  // vs 4.1e-4). Both are refined first, then ranked.
  std::vector<std::pair<double, Rigid3d>> refined;
  for (size_t i = 0; i < rvecs.size(); ++i) {
    const Rigid3d cam_from_turned = FromRvecTvec(rvecs[i], tvecs[i]);
    Rigid3d pose(cam_from_turned.rotation * turned_from_tag, cam_from_turned.translation);
    if (!IsFinite(pose) || !(pose.translation.z() > 0)) continue;
    // Plain least squares in normalised coordinates: four corners, no outliers to bound.
    double error = 0;
    pose = RefinePose(corners_in_tag, observed, all_four, 1.0, 1.0, pose, 0.0, 30, &error);
    if (std::isfinite(error) && IsFinite(pose) && pose.translation.z() > 0) refined.emplace_back(error, pose);
  }
  std::stable_sort(refined.begin(), refined.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Rigid3d> out;
  for (const auto& [error, pose] : refined) out.push_back(pose);
  return out;
}

double MeasureCornerNoisePx(const std::vector<std::array<Eigen::Vector2d, 4>>& tags_normalized,
                            const std::vector<double>& sizes_m, double fx, double fy) {
  std::vector<double> squared;
  squared.reserve(tags_normalized.size());
  for (size_t t = 0; t < tags_normalized.size() && t < sizes_m.size(); ++t) {
    const auto candidates = TagPoseCandidates(tags_normalized[t], sizes_m[t]);
    if (candidates.empty()) continue;
    double sum = 0;
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d e = (candidates.front() * TagCornerInTag(k, sizes_m[t])).hnormalized() - tags_normalized[t][k];
      sum += fx * fx * e.x() * e.x() + fy * fy * e.y() * e.y();
    }
    squared.push_back(sum);
  }
  if (squared.empty()) return 0.0;
  std::nth_element(squared.begin(), squared.begin() + squared.size() / 2, squared.end());
  return std::sqrt(squared[squared.size() / 2] / (2.0 * std::log(2.0)));
}

namespace {

// Why these correspondences cannot give a pose (too few, collinear in the
// world or in the image), or empty when they can.
std::string UnusableInput(const std::vector<Eigen::Vector3d>& points_in_world,
                          const std::vector<Eigen::Vector2d>& normalized) {
  const size_t n = points_in_world.size();
  if (n != normalized.size()) return "internal: points and observations differ in number";
  if (n < 4) return "only " + std::to_string(n) + " corner correspondences (need 4)";
  const Eigen::Vector3d spread = Spread(points_in_world);
  if (!(spread(0) > 1e-18) || spread(1) <= 1e-10 * spread(0)) {
    return "degenerate geometry: the target corners are collinear";
  }
  if (ImagePointsCollinear(normalized)) return "degenerate geometry: the corners are collinear in the image";
  return "";
}

// EPnP or SQPnP on the `use` correspondences, its pose evaluated as a
// candidate; nothing when the solver fails.
void AddPnpCandidate(const std::vector<Eigen::Vector3d>& points_in_world, const std::vector<Eigen::Vector2d>& normalized,
                     PoseMethod method, const std::vector<int>& use, const CandidateEvaluator& evaluator,
                     std::vector<Candidate>* candidates) {
  try {
    cv::Mat rvec, tvec;
    const bool ok = cv::solvePnP(ToCv(points_in_world, use), ToCv(normalized, use), cv::Mat::eye(3, 3, CV_64F), cv::noArray(),
                                 rvec, tvec, false, method == PoseMethod::kSqpnp ? cv::SOLVEPNP_SQPNP : cv::SOLVEPNP_EPNP);
    const Rigid3d pose = ok ? FromRvecTvec(rvec, tvec) : Rigid3d();
    if (ok && pose.translation.allFinite()) candidates->push_back(evaluator.Evaluate(method, pose, use));
  } catch (const cv::Exception&) {
    // Degenerate samples can make OpenCV throw; the other solvers decide.
  }
}

// EPnP inside RANSAC over all correspondences (f: the focal length that
// turns the pixel threshold into normalised units), evaluated on its
// inliers; nothing when RANSAC fails.
void AddRansacCandidate(const std::vector<Eigen::Vector3d>& points_in_world, const std::vector<Eigen::Vector2d>& normalized,
                        const std::vector<int>& all, double f, const PoseEstimatorOptions& options,
                        const CandidateEvaluator& evaluator, std::vector<Candidate>* candidates) {
  try {
    cv::Mat rvec, tvec;
    std::vector<int> support;
    const bool ok = cv::solvePnPRansac(
        ToCv(points_in_world, all), ToCv(normalized, all), cv::Mat::eye(3, 3, CV_64F), cv::noArray(), rvec, tvec, false,
        options.ransac_iterations, static_cast<float>(std::max(options.ransac_threshold_px, 4.0 * options.corner_sigma_px) / f),
        options.ransac_confidence, support, cv::SOLVEPNP_EPNP);
    const Rigid3d pose = ok ? FromRvecTvec(rvec, tvec) : Rigid3d();
    if (ok && pose.translation.allFinite()) candidates->push_back(evaluator.Evaluate(PoseMethod::kEpnp, pose, support));
  } catch (const cv::Exception&) {
    // Degenerate samples can make OpenCV throw; the other solvers decide.
  }
}

// IPPE's two solutions from the `support` correspondences (nearly coplanar
// points), each evaluated as a candidate.
void AddIppeCandidates(const std::vector<Eigen::Vector3d>& points_in_world, const std::vector<Eigen::Vector2d>& normalized,
                       const std::vector<int>& support, const CandidateEvaluator& evaluator,
                       std::vector<Candidate>* candidates) {
  try {
    std::vector<cv::Mat> rvecs, tvecs;
    cv::solvePnPGeneric(ToCv(points_in_world, support), ToCv(normalized, support), cv::Mat::eye(3, 3, CV_64F),
                        cv::noArray(), rvecs, tvecs, false, cv::SOLVEPNP_IPPE);
    for (size_t i = 0; i < rvecs.size(); ++i) {
      const Rigid3d pose = FromRvecTvec(rvecs[i], tvecs[i]);
      if (pose.translation.allFinite()) candidates->push_back(evaluator.Evaluate(PoseMethod::kIppe, pose, support));
    }
  } catch (const cv::Exception&) {
    // Degenerate input can make OpenCV throw; the other candidates decide.
  }
}

}  // namespace

PoseResult EstimatePose(const std::vector<Eigen::Vector3d>& points_in_world,
                        const std::vector<Eigen::Vector2d>& normalized, double fx, double fy,
                        const std::optional<Rigid3d>& previous, const PoseEstimatorOptions& options) {
  PoseResult result;
  result.reason = UnusableInput(points_in_world, normalized);
  if (!result.reason.empty()) return result;
  const Eigen::Vector3d spread = Spread(points_in_world);
  const bool nearly_planar = std::sqrt(spread(2) / spread(0)) < options.planarity_ratio;

  CandidateEvaluator evaluator(points_in_world, normalized, fx, fy, previous, options);
  const std::vector<int> all = evaluator.AllIndices();
  std::vector<Candidate> candidates;

  // 1. EPnP on all correspondences (tag ids make outliers rare, and one
  // solve costs far less than RANSAC); 2. SQPnP on all when EPnP's pose
  // fails a check or the points are nearly coplanar (where EPnP + LM was
  // measured 25-40 degrees off); 3. only when neither fits every
  // correspondence, EPnP inside RANSAC and SQPnP on its inliers.
  auto fits_all = [&candidates] {
    for (const auto& c : candidates) {
      if (c.passes && c.inlier_ratio >= 1.0) return true;
    }
    return false;
  };
  AddPnpCandidate(points_in_world, normalized, PoseMethod::kEpnp, all, evaluator, &candidates);
  const bool epnp_passed = !candidates.empty() && candidates.back().passes;
  if (!epnp_passed || nearly_planar) AddPnpCandidate(points_in_world, normalized, PoseMethod::kSqpnp, all, evaluator, &candidates);
  if (!fits_all()) {
    AddRansacCandidate(points_in_world, normalized, all, 0.5 * (fx + fy), options, evaluator, &candidates);
    if (!candidates.empty() && candidates.back().passes && candidates.back().inliers.size() < all.size()) {
      AddPnpCandidate(points_in_world, normalized, PoseMethod::kSqpnp, candidates.back().inliers, evaluator, &candidates);
    }
  }
  std::vector<int> support = all;
  for (const auto& c : candidates) {
    if (c.passes && c.inliers.size() >= 4 && c.inliers.size() < support.size()) support = c.inliers;
  }
  // 4. IPPE's two planar solutions, for nearly coplanar points.
  if (nearly_planar) AddIppeCandidates(points_in_world, normalized, support, evaluator, &candidates);

  const Candidate* chosen = Choose(candidates, options.max_rotation_jump_deg);
  if (!chosen) {
    result.reason = candidates.empty() ? "no PnP solver found a pose" : "pose check failed: " + candidates[0].failure;
    return result;
  }
  result.registered = true;
  result.cam_from_world = chosen->cam_from_world;
  result.inliers = chosen->inliers;
  result.rms_px = chosen->rms_px;
  result.method = chosen->method;
  result.fell_back = chosen->method != PoseMethod::kEpnp && !epnp_passed;
  return result;
}

}  // namespace tagsfm
