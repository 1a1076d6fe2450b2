#include <algorithm>
#include <cmath>
#include <string>

#include "tagsfm/capture/recording.h"
#include "tagsfm/detect/tag_detector.h"

namespace tagsfm {

const char* CornerRefinementName(CornerRefinement refinement) {
  switch (refinement) {
    case CornerRefinement::kNone: return "none";
    case CornerRefinement::kAprilTag: return "apriltag";
    case CornerRefinement::kCornerSubPix: return "cornersubpix";
    case CornerRefinement::kEdgeLineFit: return "edgelinefit";
  }
  return "unknown";
}

Result<CornerRefinement> ParseCornerRefinement(const std::string& name) {
  for (CornerRefinement r : {CornerRefinement::kNone, CornerRefinement::kAprilTag, CornerRefinement::kCornerSubPix,
                             CornerRefinement::kEdgeLineFit}) {
    if (name == CornerRefinementName(r)) return r;
  }
  return MakeError("refinement: unknown corner refinement '" + name +
                   "' (known: none, apriltag, cornersubpix, edgelinefit)");
}

Status TagDetectorOptions::Check() const {
  const auto& known = KnownTagFamilies();
  if (std::find(known.begin(), known.end(), family) == known.end()) {
    return MakeError("family: unknown tag family '" + family + "'");
  }
  if (!(quad_decimate >= 1.0f && quad_decimate <= 16.0f)) {
    return MakeError("quad_decimate must be in [1, 16] (got " + std::to_string(quad_decimate) + ")");
  }
  if (!std::isfinite(quad_sigma) || std::abs(quad_sigma) > 10.0f) {
    return MakeError("quad_sigma must be in [-10, 10] (got " + std::to_string(quad_sigma) + ")");
  }
  if (threads < 1 || threads > 64) return MakeError("threads must be in [1, 64] (got " + std::to_string(threads) + ")");
  if (!(decode_sharpening >= 0.0 && decode_sharpening <= 10.0)) {
    return MakeError("decode_sharpening must be in [0, 10] (got " + std::to_string(decode_sharpening) + ")");
  }
  if (!std::isfinite(min_decision_margin) || min_decision_margin < 0.0) {
    return MakeError("min_decision_margin must be >= 0 (got " + std::to_string(min_decision_margin) + ")");
  }
  if (max_hamming < 0 || max_hamming > 2) {
    return MakeError("max_hamming must be in [0, 2] (got " + std::to_string(max_hamming) + ")");
  }
  if (!(small_tag_min_margin >= 0.0 && small_tag_min_margin < 0.5)) {
    return MakeError("small_tag_min_margin must be in [0, 0.5) (got " + std::to_string(small_tag_min_margin) + ")");
  }
  return Status::Ok();
}

}  // namespace tagsfm
