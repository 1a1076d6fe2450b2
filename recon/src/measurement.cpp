#include "tagsfm/recon/measurement.h"

#include <algorithm>
#include <cmath>
#include <iterator>

#include "tagsfm/core/file_util.h"
#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm {
namespace {

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

}  // namespace

Eigen::Vector3d TargetPointRef::PointOn(const TagCorners& corners) const {
  return this->corner < 0 ? TagCenter(corners) : corners[static_cast<size_t>(this->corner)];
}

std::string TargetPointRef::ToString() const {
  return corner < 0 ? "tag " + std::to_string(tag) : "tag " + std::to_string(tag) + " corner " + std::to_string(corner);
}

Result<TargetPointRef> ParseTargetPointRef(const std::string& text) {
  TargetPointRef ref;
  const size_t colon = text.find(':');
  long long id = 0, corner = -1;
  if (!ParseInt64(text.substr(0, colon), &id) ||
      (colon != std::string::npos && (!ParseInt64(text.substr(colon + 1), &corner) || corner < 0 || corner > 3))) {
    return MakeError("'" + text + "' is not a target: give a tag id (its centre) or ID:CORNER with corner 0-3");
  }
  ref.tag = static_cast<TagId>(id);
  ref.corner = static_cast<int>(corner);
  return ref;
}

Result<Measurement> MeasureDistance(const TargetCornerMap& targets, const std::optional<TagCovariance>& covariance,
                                    const TargetPointRef& a, const TargetPointRef& b, double scale_sigma_rel) {
  auto ia = targets.find(a.tag), ib = targets.find(b.tag);
  if (ia == targets.end()) return MakeError("tag " + std::to_string(a.tag) + " is not in the result's targets");
  if (ib == targets.end()) return MakeError("tag " + std::to_string(b.tag) + " is not in the result's targets");
  Measurement m;
  m.a = a.PointOn(ia->second);
  m.b = b.PointOn(ib->second);
  const Eigen::Vector3d diff = m.a - m.b;
  m.distance_m = diff.norm();
  if (!covariance) {
    m.note = "no covariance in the result (targets_cov.csv): standard deviation unknown";
    return m;
  }
  // Point p = R c + t of a tag pose perturbed on the left by the rotation
  // 2*delta (Ceres' EigenQuaternionManifold) and by dt: dp = -2 [R c]x delta + dt.
  auto jacobian = [](const TagCorners& corners, const Eigen::Vector3d& point) {
    Eigen::Matrix<double, 3, 6> j;
    j.leftCols<3>() = -2.0 * Skew(point - TagCenter(corners));
    j.rightCols<3>() = Eigen::Matrix3d::Identity();
    return j;
  };
  auto index_of = [&covariance](TagId id) -> int {
    for (size_t i = 0; i < covariance->ids.size(); ++i) {
      if (covariance->ids[i] == id) return static_cast<int>(i);
    }
    return -1;
  };
  const Eigen::RowVector3d u = m.distance_m > 0 ? Eigen::RowVector3d((diff / m.distance_m).transpose()) : Eigen::RowVector3d::Zero();
  struct Term {
    int index;
    Eigen::Matrix<double, 1, 6> gradient;
  };
  std::vector<Term> terms;
  std::vector<std::string> fixed;
  const int index_a = index_of(a.tag), index_b = index_of(b.tag);
  if (index_a >= 0) terms.push_back({index_a, u * jacobian(ia->second, m.a)});
  else fixed.push_back(std::to_string(a.tag));
  if (index_b >= 0) terms.push_back({index_b, -u * jacobian(ib->second, m.b)});
  else if (b.tag != a.tag) fixed.push_back(std::to_string(b.tag));
  double variance = 0;
  for (const auto& s : terms) {
    for (const auto& t : terms) {
      variance += (s.gradient * covariance->covariance.block<6, 6>(6 * s.index, 6 * t.index) * t.gradient.transpose())(0, 0);
    }
  }
  const double scale_part = scale_sigma_rel * m.distance_m;
  m.sigma_m = std::sqrt(std::max(variance, 0.0) + scale_part * scale_part);
  if (!fixed.empty()) {
    m.note = "held fixed in the adjustment (known map or the world's anchor): tag";
    for (const auto& id : fixed) m.note += " " + id;
  }
  return m;
}

std::vector<TagPairMeasurement> MeasureAllTagPairs(const TargetCornerMap& targets,
                                                   const std::optional<TagCovariance>& covariance,
                                                   double scale_sigma_rel) {
  std::vector<TagPairMeasurement> pairs;
  for (auto a = targets.begin(); a != targets.end(); ++a) {
    for (auto b = std::next(a); b != targets.end(); ++b) {
      TargetPointRef ra, rb;
      ra.tag = a->first;
      rb.tag = b->first;
      // Both tags are in `targets`, so this cannot fail.
      Result<Measurement> m = MeasureDistance(targets, covariance, ra, rb, scale_sigma_rel);
      if (m) pairs.push_back({a->first, b->first, std::move(*m)});
    }
  }
  std::stable_sort(pairs.begin(), pairs.end(), [](const TagPairMeasurement& x, const TagPairMeasurement& y) {
    return x.measurement.distance_m < y.measurement.distance_m;
  });
  return pairs;
}

std::optional<double> MapScaleSigmaRel(const TargetCornerMap& targets, const TagCovariance& covariance) {
  if (targets.size() < 2) return std::nullopt;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& [id, corners] : targets) centroid += TagCenter(corners);
  centroid /= static_cast<double>(targets.size());
  double spread = 0;  // sum of squared distances from the centroid
  for (const auto& [id, corners] : targets) spread += (TagCenter(corners) - centroid).squaredNorm();
  if (!(spread > 0)) return std::nullopt;
  // d(scale) = sum_i (c_i - centroid) . dc_i / spread, dc_i the translation part of tag i's perturbation.
  const size_t n = covariance.ids.size();
  Eigen::VectorXd gradient = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(6 * n));
  for (size_t i = 0; i < n; ++i) {
    const auto tag = targets.find(covariance.ids[i]);
    if (tag == targets.end()) continue;
    gradient.segment<3>(static_cast<Eigen::Index>(6 * i + 3)) = (TagCenter(tag->second) - centroid) / spread;
  }
  const double variance = gradient.dot(covariance.covariance * gradient);
  return std::sqrt(std::max(variance, 0.0));
}

}  // namespace tagsfm
