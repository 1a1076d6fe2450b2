#include "adjustment_covariance.h"

#include <algorithm>
#include <array>
#include <map>
#include <set>

#include <Eigen/Dense>

namespace tagsfm {
namespace {

using Matrix36d = Eigen::Matrix<double, 3, 6>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

// The learned tags whose poses the adjustment varied, in id order.
std::vector<double*> LearnedTagBlocks(ceres::Problem* problem, std::map<TagId, MapTag>* tags, std::vector<TagId>* ids) {
  std::vector<double*> blocks;
  for (auto& [id, tag] : *tags) {
    if (tag.known || tag.anchor || !problem->HasParameterBlock(tag.world_from_tag.data)) continue;
    blocks.push_back(tag.world_from_tag.data);
    ids->push_back(id);
  }
  return blocks;
}

// The Jacobian's columns come in three groups, and so do the normal
// equations J^T J: the feature points (3 each) and the cameras that see no
// point (6 each) are eliminated; the kept unknowns (6 each: the learned
// tags, the intrinsics, the cameras that see points) stay. A point meets
// only kept blocks, and so does an eliminated camera, so each is eliminated
// by its own small block.
struct NormalBlocks {
  std::vector<Eigen::Matrix3d> h_pp;
  std::vector<std::map<int, Matrix36d>> h_pk;
  std::vector<Matrix6d> h_cc;
  std::vector<std::map<int, Matrix6d>> h_ck;
  Eigen::MatrixXd h_kk;
};

// Accumulated row by row of the sparse Jacobian. A row meets at most one
// point or eliminated camera and up to three kept blocks (a camera, a tag,
// the intrinsics).
NormalBlocks AccumulateNormalBlocks(const ceres::CRSMatrix& jacobian, int points, int cameras, int kept_blocks) {
  NormalBlocks n;
  n.h_pp.assign(static_cast<size_t>(points), Eigen::Matrix3d::Zero());
  n.h_pk.resize(static_cast<size_t>(points));
  n.h_cc.assign(static_cast<size_t>(cameras), Matrix6d::Zero());
  n.h_ck.resize(static_cast<size_t>(cameras));
  n.h_kk = Eigen::MatrixXd::Zero(6 * kept_blocks, 6 * kept_blocks);
  const int point_columns = 3 * points, camera_columns = 6 * cameras;
  for (int r = 0; r < jacobian.num_rows; ++r) {
    int point = -1, camera = -1;
    Eigen::Vector3d jp = Eigen::Vector3d::Zero();
    Vector6d jc = Vector6d::Zero();
    std::array<std::pair<int, Vector6d>, 3> kept;  // block, its row of the Jacobian
    int n_kept = 0;
    for (int k = jacobian.rows[r]; k < jacobian.rows[r + 1]; ++k) {
      const int col = jacobian.cols[k];
      const double value = jacobian.values[k];
      if (col < point_columns) {
        point = col / 3;
        jp(col % 3) = value;
        continue;
      }
      if (col < point_columns + camera_columns) {
        camera = (col - point_columns) / 6;
        jc((col - point_columns) % 6) = value;
        continue;
      }
      const int block = (col - point_columns - camera_columns) / 6;
      if (n_kept == 0 || kept[static_cast<size_t>(n_kept - 1)].first != block) {
        if (n_kept == 3) continue;  // not a residual of this adjustment's kinds
        kept[static_cast<size_t>(n_kept++)] = {block, Vector6d::Zero()};
      }
      kept[static_cast<size_t>(n_kept - 1)].second((col - point_columns - camera_columns) % 6) = value;
    }
    if (point >= 0) n.h_pp[static_cast<size_t>(point)] += jp * jp.transpose();
    if (camera >= 0) n.h_cc[static_cast<size_t>(camera)] += jc * jc.transpose();
    for (int a = 0; a < n_kept; ++a) {
      const auto& [block_a, ja] = kept[static_cast<size_t>(a)];
      for (int b = 0; b < n_kept; ++b) {
        const auto& [block_b, jb] = kept[static_cast<size_t>(b)];
        n.h_kk.block<6, 6>(6 * block_a, 6 * block_b) += ja * jb.transpose();
      }
      if (point >= 0) {
        auto [it, inserted] = n.h_pk[static_cast<size_t>(point)].try_emplace(block_a, Matrix36d::Zero());
        it->second += jp * ja.transpose();
      }
      if (camera >= 0) {
        auto [it, inserted] = n.h_ck[static_cast<size_t>(camera)].try_emplace(block_a, Matrix6d::Zero());
        it->second += jc * ja.transpose();
      }
    }
  }
  return n;
}

// A point's 3x3 block inverted where it carries information (a point seen
// along one direction only has none along it: the pseudo-inverse then
// eliminates exactly what the point's rows hold).
Eigen::Matrix3d PseudoInverse(const Eigen::Matrix3d& h) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(h);
  const Eigen::Vector3d values = eigen.eigenvalues();
  const double floor = 1e-12 * std::max(values.maxCoeff(), 0.0);
  Eigen::Vector3d inverse = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i) {
    if (values(i) > floor) inverse(i) = 1.0 / values(i);
  }
  return eigen.eigenvectors() * inverse.asDiagonal() * eigen.eigenvectors().transpose();
}

// The points and cameras eliminated: S = H_kk - sum H_kx H_xx^-1 H_xk, the
// kept blocks' information with every point and every other camera free.
Eigen::MatrixXd KeptSchurComplement(const NormalBlocks& n) {
  Eigen::MatrixXd s = n.h_kk;
  for (size_t p = 0; p < n.h_pp.size(); ++p) {
    const Eigen::Matrix3d h_pp_inverse = PseudoInverse(n.h_pp[p]);
    for (const auto& [a, h_pa] : n.h_pk[p]) {
      const Matrix36d x_a = h_pp_inverse * h_pa;
      for (const auto& [b, h_pb] : n.h_pk[p]) s.block<6, 6>(6 * b, 6 * a) -= h_pb.transpose() * x_a;
    }
  }
  for (size_t c = 0; c < n.h_cc.size(); ++c) {
    const Eigen::LDLT<Matrix6d> h_cc_inverse(n.h_cc[c]);
    if (h_cc_inverse.info() != Eigen::Success) continue;
    std::map<int, Matrix6d> solved;  // H_cc^-1 H_cb
    for (const auto& [b, h_cb] : n.h_ck[c]) solved[b] = h_cc_inverse.solve(h_cb);
    for (const auto& [a, h_ca] : n.h_ck[c]) {
      for (const auto& [b, x_b] : solved) s.block<6, 6>(6 * a, 6 * b) -= h_ca.transpose() * x_b;
    }
  }
  return s;
}

}  // namespace

// (J^T J)^-1 restricted to the tags and intrinsics, by eliminating the
// points and the cameras (Schur complements), so that its cost grows with
// the observations and the cameras that see points, not with the square of
// all frames. With the intrinsics among the unknowns, the tags' covariance
// includes what their uncertainty does to the map.
void ComputeCovariance(ceres::Problem* problem, const std::vector<FrameState*>& frames, std::map<TagId, MapTag>* tags,
                       double* intrinsics, const std::vector<AdjustedPoint>* points, int target_residuals,
                       int target_parameters, GlobalAdjustmentSummary* out) {
  TagCovariance result;
  const std::vector<double*> tag_blocks = LearnedTagBlocks(problem, tags, &result.ids);
  const bool with_intrinsics = intrinsics != nullptr && problem->HasParameterBlock(intrinsics);
  if (result.ids.empty() && !with_intrinsics) {
    out->covariance_note = "no learned tags: every target was held fixed";
    return;
  }
  // The columns: the points, the cameras that see none, then the kept
  // blocks, the learned tags first (in tangent space: 6 per pose).
  std::vector<double*> point_blocks;
  std::set<FrameId> seeing_points;
  if (points) {
    for (const AdjustedPoint& p : *points) {
      double* block = const_cast<double*>(p.position.data());
      if (!problem->HasParameterBlock(block)) continue;
      point_blocks.push_back(block);
      for (const auto& [frame, pixel] : p.observations) seeing_points.insert(frame);
    }
  }
  std::vector<double*> blocks = point_blocks, kept = tag_blocks;
  if (with_intrinsics) kept.push_back(intrinsics);
  int cameras = 0;
  for (FrameState* f : frames) {
    if (!problem->HasParameterBlock(f->cam_from_world.data)) continue;
    if (seeing_points.count(f->frame)) {
      kept.push_back(f->cam_from_world.data);
    } else {
      blocks.push_back(f->cam_from_world.data);
      ++cameras;
    }
  }
  blocks.insert(blocks.end(), kept.begin(), kept.end());
  ceres::Problem::EvaluateOptions eval;
  eval.parameter_blocks = blocks;
  double cost = 0;
  std::vector<double> residuals;
  ceres::CRSMatrix jacobian;
  if (!problem->Evaluate(eval, &cost, &residuals, nullptr, &jacobian)) {
    out->covariance_note = "the adjustment's Jacobian could not be evaluated";
    return;
  }
  const int n_tags = 6 * static_cast<int>(result.ids.size());
  const int n_wanted = n_tags + (with_intrinsics ? 6 : 0);
  const NormalBlocks normal = AccumulateNormalBlocks(jacobian, static_cast<int>(point_blocks.size()), cameras,
                                                     static_cast<int>(kept.size()));
  const Eigen::LDLT<Eigen::MatrixXd> s_inverse(KeptSchurComplement(normal));
  if (s_inverse.info() != Eigen::Success || s_inverse.vectorD().minCoeff() <= 0) {
    out->covariance_note = "the adjustment's covariance could not be computed (rank deficient)";
    return;
  }
  // For unit-variance residuals; scale by the a posteriori variance of a
  // target residual, sum r^2 / (m - n) over the targets' alone. The points'
  // residuals are weighted by a floored estimate of their precision
  // (PointTerms); pooled in, their small residuals halved a rendered walk's
  // tag sigmas (a 2-view tag: 0.41 mm for an error of 0.91 mm; 0.83 mm
  // from the targets' residuals).
  double sum_squares = 0;
  const int n_target = std::min(target_residuals, static_cast<int>(residuals.size()));
  for (int i = 0; i < n_target; ++i) sum_squares += residuals[static_cast<size_t>(i)] * residuals[static_cast<size_t>(i)];
  const double dof = static_cast<double>(n_target) - target_parameters;
  const double variance = dof > 0 ? sum_squares / dof : 1.0;
  const Eigen::MatrixXd wanted =
      s_inverse.solve(Eigen::MatrixXd::Identity(6 * static_cast<int>(kept.size()), n_wanted)).topRows(n_wanted) *
      variance;
  if (with_intrinsics) out->intrinsics_covariance = wanted.block<6, 6>(n_tags, n_tags);
  if (result.ids.empty()) {
    out->covariance_note = "no learned tags: every target was held fixed";
    return;
  }
  result.covariance = wanted.topLeftCorner(n_tags, n_tags);
  out->covariance = std::move(result);
}

}  // namespace tagsfm
