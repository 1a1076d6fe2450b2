// TrackTriangulationOptions::covariance_floor_px: the noise the data show
// raises the stored covariance of a point, not which points are kept nor
// where they lie.
#include <gtest/gtest.h>

#include "tagsfm/feature/track_triangulation.h"
#include "test_camera.h"

namespace tagsfm {
namespace {

TEST(TrackCovarianceFloor, RaisesTheCovarianceOnly) {
  const CameraModel camera = testing::PinholeCamera(640, 480, 500, 319.5, 239.5);
  PoseMap poses;
  for (int i = 0; i < 4; ++i) poses[i] = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.1 * i, 0, 0));
  std::vector<FeatureTrack> tracks;
  const Eigen::Vector3d points[2] = {{0.1, 0.05, 1.0}, {0.2, -0.1, 1.2}};
  for (int id = 0; id < 2; ++id) {
    FeatureTrack track;
    track.id = id;
    for (const auto& [frame, pose] : poses) {
      TrackObservation o;
      o.frame = frame;
      o.pixel = camera.Project(pose * points[id]);
      track.observations.push_back(o);
    }
    tracks.push_back(track);
  }
  TrackTriangulationOptions options;
  options.feature_sigma_px = 0.1;
  options.max_relative_sigma = 1.0;  // exact rays: the filter is not what this tests
  const std::vector<FeaturePoint> plain = TriangulateTracks(tracks, poses, camera, options);
  options.covariance_floor_px = 0.05;  // below feature_sigma_px: nothing changes
  const std::vector<FeaturePoint> below = TriangulateTracks(tracks, poses, camera, options);
  options.covariance_floor_px = 0.3;
  const std::vector<FeaturePoint> raised = TriangulateTracks(tracks, poses, camera, options);
  ASSERT_EQ(plain.size(), 2u);
  ASSERT_EQ(below.size(), 2u);
  ASSERT_EQ(raised.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(raised[i].position, plain[i].position);
    EXPECT_TRUE(below[i].covariance.isApprox(plain[i].covariance, 1e-12));
    // Exact rays: the noise is the floor, so the covariance grows by (0.3 / 0.1)^2.
    EXPECT_TRUE(raised[i].covariance.isApprox(9.0 * plain[i].covariance, 1e-9)) << raised[i].covariance;
  }
  options.covariance_floor_px = -1;
  const Status s = options.Check();
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("covariance_floor_px"), std::string::npos);
}

}  // namespace
}  // namespace tagsfm
