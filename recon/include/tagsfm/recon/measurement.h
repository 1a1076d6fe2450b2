#pragma once
// Distances between targets of a result, with their standard deviation
// propagated from the final adjustment's covariance of the tags' poses.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/result.h"
#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

// "12" is tag 12's centre, "12:3" its corner 3 (libapriltag's order).
struct TargetPointRef {
  TagId tag = -1;
  int corner = -1;  // -1: the centre
  std::string ToString() const;
  // The point on the tag with these corners: the corner, or their centre.
  Eigen::Vector3d PointOn(const TagCorners& corners) const;
};
Result<TargetPointRef> ParseTargetPointRef(const std::string& text);

struct Measurement {
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
  double distance_m = 0;
  std::optional<double> sigma_m;  // absent without a covariance
  std::string note;               // e.g. which tags were held fixed
};

// `covariance` is the result's learned-tag covariance (targets_cov.csv);
// tags not in it (a known map's, the anchor) count as exact.
// `scale_sigma_rel` is what the images cannot see: the relative sigma of the
// map's scale (report.json's scale.sigma_rel: the tags' print tolerance, or
// the scale bars'), added as scale_sigma_rel * distance.
Result<Measurement> MeasureDistance(const TargetCornerMap& targets, const std::optional<TagCovariance>& covariance,
                                    const TargetPointRef& a, const TargetPointRef& b, double scale_sigma_rel = 0);

// The distance between two tags' centres (VDI/VDE 2634-1's length test
// takes every pair of targets as a test length).
struct TagPairMeasurement {
  TagId a = -1, b = -1;
  Measurement measurement;
};

// Every pair of tags of `targets` (a < b), centre to centre, shortest first.
std::vector<TagPairMeasurement> MeasureAllTagPairs(const TargetCornerMap& targets,
                                                   const std::optional<TagCovariance>& covariance,
                                                   double scale_sigma_rel = 0);

// How well the images alone fix the map's scale: the relative sigma of the
// scale a similarity fit of the tags' centres would find, propagated from
// the covariance to first order (the fit's scale moves by the centres'
// radial errors about their centroid). Rotating or shifting the whole map
// does not change it, so the datum the covariance is relative to does not
// matter. Tags not in the covariance count as exact. nullopt with fewer
// than two tags.
std::optional<double> MapScaleSigmaRel(const TargetCornerMap& targets, const TagCovariance& covariance);

}  // namespace tagsfm
