// The map's scale sigma (MapScaleSigmaRel) against covariances whose scale
// part is known exactly.
#include <cmath>
#include <functional>

#include <gtest/gtest.h>

#include "tagsfm/recon/measurement.h"
#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm {
namespace {

// Tags on three walls of a room, tag 0 (the anchor) at the origin.
TargetCornerMap Room() {
  const Eigen::Vector3d centres[6] = {{0, 0, 0}, {1.5, 0.2, 0}, {3.0, -0.1, 0.4},
                                      {3.2, 1.0, 2.0}, {-0.3, 0.5, 2.5}, {1.0, 1.2, 4.0}};
  TargetCornerMap map;
  for (int id = 0; id < 6; ++id) {
    const Eigen::Vector3d c = centres[id];
    map[id] = {c + Eigen::Vector3d(-0.03, -0.03, 0), c + Eigen::Vector3d(0.03, -0.03, 0),
               c + Eigen::Vector3d(0.03, 0.03, 0), c + Eigen::Vector3d(-0.03, 0.03, 0)};
  }
  return map;
}

// The learned tags (all but the anchor) with a zero covariance.
TagCovariance EmptyCovariance(const TargetCornerMap& map) {
  TagCovariance c;
  for (const auto& [id, corners] : map) {
    if (id != 0) c.ids.push_back(id);
  }
  c.covariance = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(6 * c.ids.size()),
                                       static_cast<Eigen::Index>(6 * c.ids.size()));
  return c;
}

// The translation parts of every learned tag moved by `move(centre)`.
Eigen::VectorXd Direction(const TargetCornerMap& map, const TagCovariance& c,
                          const std::function<Eigen::Vector3d(const Eigen::Vector3d&)>& move) {
  Eigen::VectorXd d = Eigen::VectorXd::Zero(c.covariance.rows());
  for (size_t i = 0; i < c.ids.size(); ++i) {
    d.segment<3>(static_cast<Eigen::Index>(6 * i + 3)) = move(TagCenter(map.at(c.ids[i])));
  }
  return d;
}

TEST(MapScaleSigma, AScaleAboutTheAnchorIsFoundExactly) {
  const TargetCornerMap map = Room();
  TagCovariance c = EmptyCovariance(map);
  // The whole map scaled about the anchor by 1 + s, s with sigma 80 ppm.
  const Eigen::VectorXd scale = Direction(map, c, [](const Eigen::Vector3d& p) { return p; });
  c.covariance += 80e-6 * 80e-6 * scale * scale.transpose();
  const auto sigma = MapScaleSigmaRel(map, c);
  ASSERT_TRUE(sigma.has_value());
  EXPECT_NEAR(*sigma, 80e-6, 1e-9);
}

// The anchor holds the datum, so the anchor's own orientation, seen from
// one small tag, shows in the covariance as the learned tags turning about
// it together (the metres of sigma_mm far from the anchor): not a scale.
TEST(MapScaleSigma, TurningTheWholeMapAboutTheAnchorAddsNothing) {
  const TargetCornerMap map = Room();
  TagCovariance c = EmptyCovariance(map);
  const Eigen::Vector3d axis = Eigen::Vector3d(0.3, -1, 0.5).normalized();
  const Eigen::VectorXd turn = Direction(map, c, [&](const Eigen::Vector3d& p) { return axis.cross(p); });
  c.covariance += 1e-4 * turn * turn.transpose();
  const auto datum_only = MapScaleSigmaRel(map, c);
  ASSERT_TRUE(datum_only.has_value());
  EXPECT_LT(*datum_only, 1e-9);
  // The same on top of a known scale part.
  const Eigen::VectorXd scale = Direction(map, c, [](const Eigen::Vector3d& p) { return p; });
  c.covariance += 50e-6 * 50e-6 * scale * scale.transpose();
  EXPECT_NEAR(*MapScaleSigmaRel(map, c), 50e-6, 1e-9);
}

TEST(MapScaleSigma, IndependentTagsGiveTheirSigmaOverTheMapsSpread) {
  const TargetCornerMap map = Room();
  TagCovariance c = EmptyCovariance(map);
  // Each learned tag 0.5 mm on each axis, independent; the anchor exact:
  // variance = sum over learned tags of |c_i - centroid|^2 * s^2 / spread^2.
  const double s = 0.5e-3;
  for (size_t i = 0; i < c.ids.size(); ++i) {
    c.covariance.block<3, 3>(static_cast<Eigen::Index>(6 * i + 3), static_cast<Eigen::Index>(6 * i + 3)) =
        s * s * Eigen::Matrix3d::Identity();
  }
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& [id, corners] : map) centroid += TagCenter(corners) / 6.0;
  double spread = 0, learned = 0;
  for (const auto& [id, corners] : map) {
    const double r2 = (TagCenter(corners) - centroid).squaredNorm();
    spread += r2;
    if (id != 0) learned += r2;
  }
  EXPECT_NEAR(*MapScaleSigmaRel(map, c), s * std::sqrt(learned) / spread, 1e-12);
}

TEST(MapScaleSigma, OneTagHasNoScale) {
  TargetCornerMap map = Room();
  for (TagId id = 1; id < 6; ++id) map.erase(id);
  TagCovariance c;
  EXPECT_FALSE(MapScaleSigmaRel(map, c).has_value());
}

}  // namespace
}  // namespace tagsfm
