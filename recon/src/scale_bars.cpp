#include "tagsfm/recon/scale_bars.h"

#include <cmath>

#include "tagsfm/recon/measurement.h"

namespace tagsfm {
namespace {

TargetPointRef RefOf(const ScaleBarPoint& p) {
  TargetPointRef ref;
  ref.tag = p.tag;
  ref.corner = p.corner;
  return ref;
}

}  // namespace

Result<MapScale> FitScaleBars(const std::vector<ScaleBar>& bars, const TargetCornerMap& targets,
                                   const std::optional<TagCovariance>& covariance) {
  MapScale out;
  out.source = "scale bars";
  double sum_w = 0, sum_ws = 0;
  for (size_t i = 0; i < bars.size(); ++i) {
    const ScaleBar& bar = bars[i];
    Result<Measurement> m = MeasureDistance(targets, covariance, RefOf(bar.a), RefOf(bar.b));
    if (!m) return MakeError("targets.scale_bars[" + std::to_string(i) + "]: " + m.error().message);
    if (!(m->distance_m > 0)) return MakeError("targets.scale_bars[" + std::to_string(i) + "]: both ends coincide");
    ScaleBarCheck check;
    check.bar = bar;
    check.measured_m = m->distance_m;
    check.sigma_m = m->sigma_m.value_or(0.0);
    // s_i = L / l; its relative variance is the certificate's plus the map's.
    const double s = bar.length_m / check.measured_m;
    const double rel_var = std::pow(bar.sigma_m / bar.length_m, 2) + std::pow(check.sigma_m / check.measured_m, 2);
    const double w = 1.0 / rel_var;
    sum_w += w;
    sum_ws += w * s;
    out.bars.push_back(check);
  }
  if (out.bars.empty()) return MakeError("no scale bars");
  out.scale = sum_ws / sum_w;
  out.sigma_rel = 1.0 / std::sqrt(sum_w);
  for (ScaleBarCheck& c : out.bars) c.residual_m = out.scale * c.measured_m - c.bar.length_m;
  return out;
}

void ScaleScene(double scale, std::vector<FrameState*>* frames, std::map<TagId, MapTag>* tags,
                std::optional<TagCovariance>* covariance) {
  for (FrameState* f : *frames) {
    for (int k = 4; k < 7; ++k) f->cam_from_world.data[k] *= scale;
  }
  for (auto& [id, tag] : *tags) {
    if (tag.known) continue;
    for (int k = 4; k < 7; ++k) tag.world_from_tag.data[k] *= scale;
    tag.size_m *= scale;
  }
  if (covariance && *covariance) {
    Eigen::MatrixXd& c = (*covariance)->covariance;
    for (Eigen::Index i = 0; i < c.rows(); ++i) {
      if (i % 6 >= 3) {
        c.row(i) *= scale;
        c.col(i) *= scale;
      }
    }
  }
}

}  // namespace tagsfm
