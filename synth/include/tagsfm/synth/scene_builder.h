#pragma once
// The scenes `tagsfm synth` knows, built deterministically from the options.
#include "tagsfm/core/result.h"
#include "tagsfm/synth/scene.h"
#include "tagsfm/synth/synth_options.h"

namespace tagsfm::synth {

// "box": a 0.9 x 0.5 x 1.8 m box (like the paper's armoire) on a textured floor
//        before a back wall, 37 targets on its visible faces and the floor;
// "wall": a flat 4 x 2.5 m textured wall with 24 targets.
Result<Scene> BuildScene(const SynthOptions& options);

// The modules of tag `id` of `family`, from libapriltag's apriltag_to_image.
Result<TagPattern> LoadTagPattern(const std::string& family, TagId id);
// How many codes the family has.
Result<int> TagFamilySize(const std::string& family);

// A procedural albedo texture (multi-scale value noise, blobs, strokes; no
// dark squares that could pass for a tag), deterministic in `seed`.
cv::Mat1f MakeTexture(int cols, int rows, double texel_m, std::uint64_t seed);

}  // namespace tagsfm::synth
