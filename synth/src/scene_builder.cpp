// The box, wall and room scenes: faces, textures and a random tag layout.
#include "tagsfm/synth/scene_builder.h"

#include <algorithm>
#include <cmath>

namespace tagsfm::synth {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

struct FaceSpec {
  const char* name;
  Vector3d origin, edge_u, edge_v;
  double shade;
  double texel_m;
};

// Where on a face tags go, in metres along its edges, and how many.
struct TagRegion {
  int face;
  Vector2d min, max;
  int count;
  double max_angle_rad;  // in-plane rotation in [-max, max]
};

void AddFace(Scene* scene, const FaceSpec& spec, std::uint64_t seed) {
  SceneFace face;
  face.name = spec.name;
  face.rect = Rectangle3d{spec.origin, spec.edge_u, spec.edge_v};
  face.shade = spec.shade;
  const int cols = static_cast<int>(std::ceil(spec.edge_u.norm() / spec.texel_m));
  const int rows = static_cast<int>(std::ceil(spec.edge_v.norm() / spec.texel_m));
  face.texture = MakeTexture(cols, rows, spec.texel_m, seed * 7919 + scene->faces.size());
  scene->faces.push_back(std::move(face));
}

// Random non-overlapping positions; ids continue from the tags already placed.
Status PlaceTags(Scene* scene, const TagRegion& region, const SynthOptions& options, int family_size, cv::RNG& rng) {
  const std::string& face_name = scene->faces[static_cast<size_t>(region.face)].name;
  for (int placed = 0; placed < region.count; ++placed) {
    const TagId id = static_cast<TagId>(scene->tags.size());
    if (id >= family_size) return Status::Ok();  // a small family: fewer targets
    Result<TagPattern> pattern = LoadTagPattern(options.family, id);
    if (!pattern) return pattern.error();
    // The printed sheet: the detector's square plus the margin round it. The
    // spacing is the larger of that and the old sheet (the image plus a
    // module of paper), so that margins 1 and 2 give the same layout.
    const double module_m = options.tag_size / pattern->width_at_border;
    const double sheet_m =
        std::max(pattern->total_width + 2.0, pattern->width_at_border + 2.0 * options.tag_margin) * module_m;
    const double spacing_m = 1.5 * sheet_m;  // room for any rotation of both sheets
    bool found = false;
    for (int attempt = 0; attempt < 2000 && !found; ++attempt) {
      const Vector2d centre(rng.uniform(region.min.x() + 0.75 * sheet_m, region.max.x() - 0.75 * sheet_m),
                            rng.uniform(region.min.y() + 0.75 * sheet_m, region.max.y() - 0.75 * sheet_m));
      found = true;
      for (const PlacedTag& other : scene->tags) {
        if (other.face == region.face && (other.centre_in_face - centre).norm() < spacing_m) found = false;
      }
      if (found) {
        PlacedTag tag;
        tag.id = id;
        tag.face = region.face;
        tag.centre_in_face = centre;
        tag.angle_rad = rng.uniform(-region.max_angle_rad, region.max_angle_rad);
        tag.size_m = options.tag_size * options.print_scale;
        tag.margin_modules = options.tag_margin;
        tag.pattern = std::move(*pattern);
        scene->tags.push_back(std::move(tag));
      }
    }
    if (!found) {
      return MakeError("--tag-size " + std::to_string(options.tag_size) + ": cannot fit " +
                       std::to_string(region.count) + " tags on face " + face_name + "; use smaller tags");
    }
  }
  return Status::Ok();
}

constexpr double kUpright = 15 * M_PI / 180;  // tags on walls: roughly upright
constexpr double kAnyAngle = M_PI;            // tags lying flat: any direction

}  // namespace

Result<Scene> BuildScene(const SynthOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  Result<int> family_size = TagFamilySize(options.family);
  if (!family_size) return family_size.error();
  Scene scene;
  scene.name = options.scene;
  scene.family = options.family;
  std::vector<TagRegion> regions;
  if (options.scene == "box") {
    // Box x in [-0.45, 0.45], y in [-0.25, 0.25], z in [0, 1.8]; its front faces -y.
    const FaceSpec faces[] = {
        {"box_front", {-0.45, -0.25, 0}, {0.9, 0, 0}, {0, 0, 1.8}, 0.95, 0.002},
        {"box_left", {-0.45, 0.25, 0}, {0, -0.5, 0}, {0, 0, 1.8}, 0.75, 0.002},
        {"box_right", {0.45, -0.25, 0}, {0, 0.5, 0}, {0, 0, 1.8}, 0.85, 0.002},
        {"box_top", {-0.45, -0.25, 1.8}, {0.9, 0, 0}, {0, 0.5, 0}, 1.0, 0.002},
        {"box_back", {0.45, 0.25, 0}, {-0.9, 0, 0}, {0, 0, 1.8}, 0.7, 0.004},
        {"floor", {-4, -4, 0}, {8, 0, 0}, {0, 5.5, 0}, 0.8, 0.004},
        {"back_wall", {-4, 1.5, 0}, {8, 0, 0}, {0, 0, 3}, 0.9, 0.004},
    };
    for (const FaceSpec& f : faces) AddFace(&scene, f, options.seed);
    // 14 + 7 + 7 + 3 + 6 = 37 targets, like the paper's armoire.
    regions = {{0, {0, 0.05}, {0.9, 1.75}, 14, kUpright},
               {1, {0, 0.05}, {0.5, 1.75}, 7, kUpright},
               {2, {0, 0.05}, {0.5, 1.75}, 7, kUpright},
               {3, {0, 0}, {0.9, 0.5}, 3, kAnyAngle},
               {5, {3.1, 2.9}, {4.9, 3.6}, 6, kAnyAngle}};  // floor in front of the box
    scene.look_at = Vector3d(0, 0, 0.9);
  } else if (options.scene == "room") {
    // A 5 x 4 x 2.6 m room seen from inside (x in [-2.5, 2.5], y in [-2, 2]):
    // each face's edge_u x edge_v points into the room, towards the camera.
    const FaceSpec faces[] = {
        {"wall_south", {2.5, -2, 0}, {-5, 0, 0}, {0, 0, 2.6}, 0.9, 0.004},
        {"wall_east", {2.5, 2, 0}, {0, -4, 0}, {0, 0, 2.6}, 0.8, 0.004},
        {"wall_north", {-2.5, 2, 0}, {5, 0, 0}, {0, 0, 2.6}, 0.95, 0.004},
        {"wall_west", {-2.5, -2, 0}, {0, 4, 0}, {0, 0, 2.6}, 0.75, 0.004},
        {"floor", {-2.5, -2, 0}, {5, 0, 0}, {0, 4, 0}, 0.7, 0.004},
        {"ceiling", {-2.5, -2, 2.6}, {0, 4, 0}, {5, 0, 0}, 1.0, 0.004},
    };
    for (const FaceSpec& f : faces) AddFace(&scene, f, options.seed);
    // 9 + 7 + 9 + 7 = 32 targets on the walls, at 0.6-2.1 m, as in a room
    // surveyed by walking round it (the loop closes on the first wall).
    regions = {{0, {0.3, 0.6}, {4.7, 2.1}, 9, kUpright},
               {1, {0.3, 0.6}, {3.7, 2.1}, 7, kUpright},
               {2, {0.3, 0.6}, {4.7, 2.1}, 9, kUpright},
               {3, {0.3, 0.6}, {3.7, 2.1}, 7, kUpright}};
    scene.look_at = Vector3d(0, 0, 1.4);
  } else {
    AddFace(&scene, {"wall", {-2, 0, 0}, {4, 0, 0}, {0, 0, 2.5}, 0.9, 0.0025}, options.seed);
    regions = {{0, {0.4, 0.3}, {3.6, 2.2}, 24, kUpright}};
    scene.look_at = Vector3d(0, 0, 1.25);
  }
  cv::RNG rng(options.seed * 104729 + 17);
  for (const TagRegion& region : regions) {
    if (Status s = PlaceTags(&scene, region, options, *family_size, rng); !s) return s.error();
  }
  return scene;
}

}  // namespace tagsfm::synth
