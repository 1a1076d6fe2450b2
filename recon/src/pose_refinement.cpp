// The one pose refinement: a frame's pose on its mapped corners (EstimatePose)
// and a single tag's pose on its four corners (TagPoseCandidates) both come
// here. A small Levenberg-Marquardt on the 6 degrees of freedom rather than a
// Ceres problem: building a Ceres problem costs more than the few iterations
// a pose needs, and the dashboard's coverage refines every tag of every frame
// (bench/pose_refinement_bench has the figures).
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "tagsfm/recon/pose_estimator.h"

namespace tagsfm {
namespace {

bool IsFinite(const Rigid3d& pose) { return pose.rotation.coeffs().allFinite() && pose.translation.allFinite(); }

// Huber's rho on a squared pixel error, as Ceres' HuberLoss defines it
// (delta <= 0: plain least squares).
double Rho(double squared, double delta) {
  if (!(delta > 0) || squared <= delta * delta) return squared;
  return 2 * delta * std::sqrt(squared) - delta * delta;
}

class PoseProblem {
 public:
  PoseProblem(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector2d>& normalized,
              const std::vector<int>& use, double fx, double fy, double huber_px)
      : points_(points), normalized_(normalized), use_(use), fx_(fx), fy_(fy), delta_(huber_px) {}

  // The robust cost (half the sum of rho, as Ceres counts it); infinite when
  // a point is behind the camera.
  double Cost(const Rigid3d& pose) const {
    double sum = 0;
    for (int i : use_) {
      const Eigen::Vector3d p = pose * points_[i];
      if (!(p.z() > 0)) return std::numeric_limits<double>::infinity();
      sum += Rho(ErrorPx(p, i).squaredNorm(), delta_);
    }
    return 0.5 * sum;
  }

  // Gauss-Newton normal equations with iteratively reweighted Huber weights;
  // the rotation steps on the left by a small rotation vector.
  void Normal(const Rigid3d& pose, Eigen::Matrix<double, 6, 6>* jtj, Eigen::Matrix<double, 6, 1>* jtr) const {
    jtj->setZero();
    jtr->setZero();
    for (int i : use_) {
      const Eigen::Vector3d rotated = pose.rotation * points_[i];
      const Eigen::Vector3d p = rotated + pose.translation;
      const double iz = 1.0 / p.z();
      Eigen::Matrix<double, 2, 3> d_proj;
      d_proj << fx_ * iz, 0, -fx_ * p.x() * iz * iz, 0, fy_ * iz, -fy_ * p.y() * iz * iz;
      Eigen::Matrix<double, 3, 6> d_point;
      // p' = exp(w) R X + t + dt  =>  dp/dw = -[R X]x, dp/dt = I.
      d_point << 0, rotated.z(), -rotated.y(), 1, 0, 0,  //
          -rotated.z(), 0, rotated.x(), 0, 1, 0,         //
          rotated.y(), -rotated.x(), 0, 0, 0, 1;
      const Eigen::Matrix<double, 2, 6> j = d_proj * d_point;
      const Eigen::Vector2d r = ErrorPx(p, i);
      const double norm = r.norm();
      const double w = (delta_ > 0 && norm > delta_) ? delta_ / norm : 1.0;
      jtj->noalias() += w * j.transpose() * j;
      jtr->noalias() += w * j.transpose() * r;
    }
  }

 private:
  Eigen::Vector2d ErrorPx(const Eigen::Vector3d& p, int i) const {
    return {fx_ * (p.x() / p.z() - normalized_[i].x()), fy_ * (p.y() / p.z() - normalized_[i].y())};
  }

  const std::vector<Eigen::Vector3d>& points_;
  const std::vector<Eigen::Vector2d>& normalized_;
  const std::vector<int>& use_;
  double fx_, fy_, delta_;
};

Rigid3d Step(const Rigid3d& pose, const Eigen::Matrix<double, 6, 1>& step) {
  const Eigen::Vector3d w = step.head<3>();
  const double angle = w.norm();
  const Eigen::Quaterniond dq =
      angle > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, w / angle)) : Eigen::Quaterniond::Identity();
  return Rigid3d((dq * pose.rotation).normalized(), pose.translation + step.tail<3>());
}

}  // namespace

Rigid3d RefinePose(const std::vector<Eigen::Vector3d>& points_in_world, const std::vector<Eigen::Vector2d>& normalized,
                   const std::vector<int>& use, double fx, double fy, const Rigid3d& initial, double huber_px,
                   int max_iterations, double* final_cost) {
  const PoseProblem problem(points_in_world, normalized, use, fx, fy, huber_px);
  Rigid3d pose = initial;
  double current = IsFinite(initial) ? problem.Cost(initial) : std::numeric_limits<double>::quiet_NaN();
  // A solver's degenerate sample can hand back a NaN rotation: returned as it
  // came, it has no inliers and fails the candidate's checks.
  double lambda = 1e-6;
  for (int iteration = 0; iteration < max_iterations && std::isfinite(current) && current > 0; ++iteration) {
    Eigen::Matrix<double, 6, 6> jtj;
    Eigen::Matrix<double, 6, 1> jtr;
    problem.Normal(pose, &jtj, &jtr);
    bool improved = false;
    while (lambda < 1e6) {
      Eigen::Matrix<double, 6, 6> damped = jtj;
      damped.diagonal() *= 1.0 + lambda;
      const Eigen::Matrix<double, 6, 1> step = -damped.ldlt().solve(jtr);
      if (!step.allFinite()) break;
      const Rigid3d trial = Step(pose, step);
      const double trial_cost = problem.Cost(trial);
      if (trial_cost < current) {
        const bool converged = current - trial_cost < 1e-12 * current;
        pose = trial;
        current = trial_cost;
        lambda = std::max(lambda * 0.1, 1e-9);
        improved = !converged;
        break;
      }
      lambda *= 10;
    }
    if (!improved) break;
  }
  if (final_cost) *final_cost = current;
  return pose;
}

}  // namespace tagsfm
