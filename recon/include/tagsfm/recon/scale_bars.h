#pragma once
// The map's scale from certified distances (recording.yaml's
// targets.scale_bars) instead of the printed tag sizes. The tags come from
// one printer, so their error is mostly one common print scale s: the
// adjustment at the nominal sizes gives a scene that is 1/s of the truth,
// and the same scene scaled by s (tags, their sizes, the cameras) fits
// every image exactly as well. So the adjustment runs at the nominal sizes
// and the scale bars then fix s, each weighted by its own sigma (the
// certificate's and the map's own for that length).
#include <optional>
#include <string>
#include <vector>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/result.h"
#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

// Errors name the bar whose tag is not mapped. Bars are taken as
// independent of each other.
Result<MapScale> FitScaleBars(const std::vector<ScaleBar>& bars, const TargetCornerMap& targets,
                                   const std::optional<TagCovariance>& covariance);

// Scales the world about its origin: camera and tag translations, tag sizes
// and the tags' covariance (translation rows and columns). Known-map tags
// are not touched (a known map fixes the scale; the caller does not scale then).
void ScaleScene(double scale, std::vector<FrameState*>* frames, std::map<TagId, MapTag>* tags,
                std::optional<TagCovariance>* covariance);

}  // namespace tagsfm
