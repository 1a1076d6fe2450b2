#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>

#include <gtest/gtest.h>

#include <set>
#include <string>

#include "tagsfm/synth/camera_path.h"
#include "tagsfm/synth/renderer.h"
#include "tagsfm/synth/scene_builder.h"

namespace tagsfm::synth {
namespace {

TEST(TagPattern, Tag36h11HasAWhiteRingAroundTheBlackSquare) {
  Result<TagPattern> pattern = LoadTagPattern("tag36h11", 0);
  ASSERT_TRUE(pattern) << pattern.error().message;
  EXPECT_EQ(pattern->total_width, 10);
  EXPECT_EQ(pattern->width_at_border, 8);
  for (int i = 0; i < 10; ++i) {
    EXPECT_TRUE(pattern->WhiteAt(i, 0) && pattern->WhiteAt(i, 9) && pattern->WhiteAt(0, i) && pattern->WhiteAt(9, i));
  }
  for (int i = 1; i < 9; ++i) {
    EXPECT_FALSE(pattern->WhiteAt(i, 1) || pattern->WhiteAt(i, 8) || pattern->WhiteAt(1, i) || pattern->WhiteAt(8, i));
  }
  EXPECT_FALSE(LoadTagPattern("tag36h11", 587));  // 587 codes: ids 0..586
  EXPECT_FALSE(LoadTagPattern("nonsense", 0));
}

TEST(TagPattern, EveryKnownFamilyLoads) {
  for (const char* family : {"tag16h5", "tag25h9", "tag36h10", "tag36h11", "tagCircle21h7", "tagCircle49h12",
                             "tagCustom48h12", "tagStandard41h12", "tagStandard52h13"}) {
    Result<TagPattern> pattern = LoadTagPattern(family, 3);
    ASSERT_TRUE(pattern) << family;
    EXPECT_GT(pattern->total_width, pattern->width_at_border) << family;
  }
}

TEST(Scene, BoxHas37DistinctSquareTargetsOnItsFaces) {
  SynthOptions options;
  Result<Scene> scene = BuildScene(options);
  ASSERT_TRUE(scene) << scene.error().message;
  ASSERT_EQ(scene->tags.size(), 37u);
  std::set<TagId> ids;
  for (const PlacedTag& tag : scene->tags) {
    ids.insert(tag.id);
    const TagCorners c = TagCornersInWorld(*scene, tag);
    const Rectangle3d& face = scene->faces[static_cast<size_t>(tag.face)].rect;
    for (int i = 0; i < 4; ++i) {
      EXPECT_NEAR((c[(i + 1) % 4] - c[i]).norm(), options.tag_size, 1e-12);
      EXPECT_LT(face.DistanceTo(c[i]), 1e-12) << "tag " << tag.id << " off its face";
    }
    // Counter-clockwise seen from the front: (c1 - c0) x (c2 - c1) along the face normal.
    EXPECT_GT((c[1] - c[0]).cross(c[2] - c[1]).dot(face.Normal()), 0) << "tag " << tag.id;
  }
  EXPECT_EQ(ids.size(), 37u);
}

TEST(Scene, WallIsOneFaceWith24Targets) {
  SynthOptions options;
  options.scene = "wall";
  Result<Scene> scene = BuildScene(options);
  ASSERT_TRUE(scene) << scene.error().message;
  EXPECT_EQ(scene->faces.size(), 1u);
  EXPECT_EQ(scene->tags.size(), 24u);
}

// The room is seen from inside: every face turns its front to the room's
// centre (the renderer draws faces one-sided), and its 32 targets sit on the
// four walls, upright and on their faces.
TEST(Scene, RoomFacesLookInwardAndItsTargetsAreOnTheWalls) {
  SynthOptions options;
  options.scene = "room";
  Result<Scene> scene = BuildScene(options);
  ASSERT_TRUE(scene) << scene.error().message;
  ASSERT_EQ(scene->faces.size(), 6u);
  for (const SceneFace& face : scene->faces) {
    const Eigen::Vector3d centre = face.rect.origin + 0.5 * (face.rect.edge_u + face.rect.edge_v);
    EXPECT_GT((scene->look_at - centre).dot(face.rect.Normal()), 0.5) << face.name << " faces away from the room";
  }
  ASSERT_EQ(scene->tags.size(), 32u);
  std::set<std::string> walls;
  for (const PlacedTag& tag : scene->tags) {
    const SceneFace& face = scene->faces[static_cast<size_t>(tag.face)];
    walls.insert(face.name);
    EXPECT_EQ(face.name.rfind("wall_", 0), 0u) << "tag " << tag.id << " on " << face.name;
    const TagCorners c = TagCornersInWorld(*scene, tag);
    for (int i = 0; i < 4; ++i) EXPECT_LT(face.rect.DistanceTo(c[i]), 1e-12) << "tag " << tag.id;
    EXPECT_GT((c[1] - c[0]).cross(c[2] - c[1]).dot(face.rect.Normal()), 0) << "tag " << tag.id;
  }
  EXPECT_EQ(walls.size(), 4u);
}

// The room's orbit turns 400 degrees from inside, so the walls it began with
// are seen again at its end: the loop closes. Smooth at 30 fps.
TEST(CameraPath, RoomOrbitTurnsRoundAndClosesTheLoop) {
  SynthOptions options;
  options.scene = "room";
  options.frames = 120;
  const Scene scene = *BuildScene(options);
  Result<CameraPath> path = MakeCameraPath(options, scene);
  ASSERT_TRUE(path) << path.error().message;
  ASSERT_EQ(path->cam_from_world.size(), 120u);
  double turned = 0;
  for (size_t i = 1; i < 120; ++i) {
    const double step = RotationAngleDeg(path->cam_from_world[i].rotation, path->cam_from_world[i - 1].rotation);
    EXPECT_LT(step, 6.0) << "frame " << i;
    turned += step;
    EXPECT_LT((path->cam_from_world[i].Center() - scene.look_at).norm(), 0.8);
  }
  EXPECT_GT(turned, 390.0);
  // The last frame looks the way the first did, within the path's wiggle.
  EXPECT_LT(RotationAngleDeg(path->cam_from_world.front().rotation, path->cam_from_world.back().rotation), 60.0);
}

TEST(Scene, TooLargeTagsAreAnErrorNamingTheOption) {
  SynthOptions options;
  options.tag_size = 0.2;
  Result<Scene> scene = BuildScene(options);
  ASSERT_FALSE(scene);
  EXPECT_NE(scene.error().message.find("--tag-size"), std::string::npos) << scene.error().message;
}

// --tag-margin m: m modules of white round the black square, the face's
// texture right beyond (whose albedo is kept below the tags' white). Frontal
// view, no blur or noise: the module centres along each edge's normal.
TEST(Scene, TagMarginIsWhiteForItsModulesAndTextureBeyond) {
  for (double margin : {1.0, 2.0, 3.0}) {
    SynthOptions options;
    options.scene = "wall";
    options.tag_margin = margin;
    Result<Scene> scene = BuildScene(options);
    ASSERT_TRUE(scene) << scene.error().message;
    const PlacedTag& tag = scene->tags[0];
    const TagCorners c = TagCornersInWorld(*scene, tag);
    const Eigen::Vector3d centre = 0.25 * (c[0] + c[1] + c[2] + c[3]);
    const Eigen::Vector3d normal = scene->faces[static_cast<size_t>(tag.face)].rect.Normal();
    CameraModel camera;
    camera.width = camera.height = 300;
    camera.fx = camera.fy = 1000;  // 15 px per module at 0.5 m
    camera.cx = camera.cy = 149.5;
    const Rigid3d cam_from_world = LookAt(centre + 0.5 * normal, centre, 0.0);
    Result<SceneRenderer> renderer = SceneRenderer::Create(camera, &*scene, 2, 1);
    ASSERT_TRUE(renderer) << renderer.error().message;
    const cv::Mat1f light = renderer->Render(cam_from_world);
    const double shade = scene->faces[static_cast<size_t>(tag.face)].shade;
    const double module_m = tag.size_m / tag.pattern.width_at_border;
    for (int e = 0; e < 4; ++e) {
      const Eigen::Vector3d mid = 0.5 * (c[e] + c[(e + 1) % 4]);
      const Eigen::Vector3d outward = (mid - centre).normalized();
      for (int k = 0; k <= static_cast<int>(margin); ++k) {
        const Eigen::Vector2d px = camera.Project(cam_from_world * (mid + (k + 0.5) * module_m * outward));
        ASSERT_TRUE(px.x() >= 0 && px.y() >= 0 && px.x() < camera.width - 1 && px.y() < camera.height - 1);
        const float value = light(static_cast<int>(std::lround(px.y())), static_cast<int>(std::lround(px.x())));
        if (k < margin) {
          EXPECT_NEAR(value, 0.92 * shade, 1e-4) << "margin " << margin << " edge " << e << " module " << k;
        } else {
          EXPECT_LT(value, 0.86 * shade) << "margin " << margin << " edge " << e << ": white beyond the margin";
        }
      }
    }
  }
}

TEST(Rectangle, DistanceToClampsToTheEdges) {
  const Rectangle3d r{{0, 0, 0}, {2, 0, 0}, {0, 1, 0}};
  EXPECT_DOUBLE_EQ(r.DistanceTo({1, 0.5, 0.3}), 0.3);
  EXPECT_DOUBLE_EQ(r.DistanceTo({3, 0.5, 0}), 1.0);
  EXPECT_DOUBLE_EQ(r.DistanceTo({3, 2, 0}), std::sqrt(2.0));
}

TEST(CameraPath, OrbitIsSmoothAt30FpsWithAllTargetsInFront) {
  SynthOptions options;
  options.frames = 30;
  const Scene scene = *BuildScene(options);
  Result<CameraPath> path = MakeCameraPath(options, scene);
  ASSERT_TRUE(path) << path.error().message;
  ASSERT_EQ(path->cam_from_world.size(), 30u);
  const TargetCornerMap targets = SceneTargets(scene);
  for (size_t i = 0; i < 30; ++i) {
    EXPECT_EQ(path->timestamps_ns[i], static_cast<std::int64_t>(i) * 1'000'000'000 / 30);
    const double distance = (path->cam_from_world[i].Center() - scene.look_at).norm();
    EXPECT_GE(distance, options.min_distance - 1e-9);
    EXPECT_LE(distance, options.max_distance + 1e-9);
    for (const auto& [id, corners] : targets) {
      for (const auto& corner : corners) EXPECT_GT((path->cam_from_world[i] * corner).z(), 0.1);
    }
    if (i > 0) {
      // 140 degrees of arc over 29 steps, plus wiggle: a video, not a jump.
      EXPECT_LT(RotationAngleDeg(path->cam_from_world[i].rotation, path->cam_from_world[i - 1].rotation), 10.0);
      EXPECT_LT((path->cam_from_world[i].Center() - path->cam_from_world[i - 1].Center()).norm(), 0.5);
    }
  }
}

// libapriltag's detector, run on a rendered view, reports the corners in the
// same order as the ground truth (its pixel centres are at +0.5).
TEST(CornerOrder, MatchesLibapriltagsDetector) {
  SynthOptions options;
  options.width = 800;
  options.height = 600;
  options.min_distance = 1.4;
  options.max_distance = 1.6;
  options.frames = 3;
  const Scene scene = *BuildScene(options);
  const CameraPath path = *MakeCameraPath(options, scene);
  const CameraModel camera = options.Camera();
  Result<SceneRenderer> renderer = SceneRenderer::Create(camera, &scene, 2, 2);
  ASSERT_TRUE(renderer);
  const TargetCornerMap targets = SceneTargets(scene);
  apriltag_family_t* family = tag36h11_create();
  apriltag_detector_t* detector = apriltag_detector_create();
  apriltag_detector_add_family(detector, family);
  detector->quad_decimate = 1;
  int checked = 0;
  for (const Rigid3d& cam_from_world : path.cam_from_world) {
    cv::Mat gray = ApplySensorModel(renderer->Render(cam_from_world), {1.0, 0.0}, 1);
    image_u8_t image{gray.cols, gray.rows, static_cast<int32_t>(gray.step), gray.data};
    zarray_t* detections = apriltag_detector_detect(detector, &image);
    for (int k = 0; k < zarray_size(detections); ++k) {
      apriltag_detection_t* d = nullptr;
      zarray_get(detections, k, &d);
      ASSERT_TRUE(targets.count(d->id)) << "detected a tag that is not in the scene: " << d->id;
      for (int c = 0; c < 4; ++c) {
        const Eigen::Vector2d truth = camera.Project(cam_from_world * targets.at(d->id)[static_cast<size_t>(c)]);
        const Eigen::Vector2d detected(d->p[c][0] - 0.5, d->p[c][1] - 0.5);
        const Eigen::Vector2d next =
            camera.Project(cam_from_world * targets.at(d->id)[static_cast<size_t>((c + 1) % 4)]);
        // A wrong order would be off by a whole edge; libapriltag's own corners
        // (no refinement) are good to about a pixel.
        EXPECT_LT((detected - truth).norm(), std::min(1.5, 0.25 * (next - truth).norm()))
            << "tag " << d->id << " corner " << c;
      }
      ++checked;
    }
    apriltag_detections_destroy(detections);
  }
  apriltag_detector_destroy(detector);
  tag36h11_destroy(family);
  EXPECT_GE(checked, 10);
}

}  // namespace
}  // namespace tagsfm::synth
