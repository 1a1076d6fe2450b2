// Corner refinement by fitting the four outer edges of the tag's square.
//
// Why edges rather than corners: a corner's position is decided by a few
// pixels around it, an edge line by every pixel along it, which divides the
// noise by ~4 on a small tag. Why a model rather than gradient centroids: on
// small, blurred tags (3 px modules, blur 0.7 px) the border's inner edge,
// one module in, overlaps the outer one wherever the data module behind the
// border is white, and pulls a centroid outward by up to 0.1 px. The decoded
// tag's layout says where those white modules are, so each edge is fitted
// with a model of the blurred outer step plus the blurred white modules
// behind the border and the adjacent edges (see EdgeModel), by Gauss-Newton
// on the pixels of a band around the edge. The band ends at the white ring
// a tag is known to have (one module: the official images printed edge to
// edge); what lies beyond has a level of its own in the model, so that a
// textured surface there does not darken the white level (it biased the
// corners -0.02 px inward at margin 1). With a camera model the fit runs
// in undistorted pixel coordinates (LocalUndistortion).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <tuple>
#include <vector>

#include <Eigen/Dense>
#include <Eigen/QR>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/detect/corner_refinement.h"
#include "tagsfm/detect/tag_layout.h"

namespace tagsfm {
namespace {

// Phi(x) and phi(x) from a table: the fit evaluates them ~10^4 times per
// tag, and exp (let alone std::erfc) dominated its cost. Cubic Hermite
// interpolation between knots 1/32 apart, with the exact derivatives
// (phi' = -x phi), is good to ~1e-9, far below what 8-bit pixels resolve.
// Each interval stores both cubics' coefficients in f (Horner: 12 flops,
// one cache line), not the knots' values and slopes (~30 flops from four
// scattered loads): ~15 % of the refinement's time saved.
struct CdfPdf {
  double cdf;
  double pdf;
};
class NormalTable {
 public:
  static constexpr double kRange = 8.0;       // beyond: 0 or 1, and 0
  static constexpr double kKnotsPerUnit = 32.0;
  static constexpr int kKnots = static_cast<int>(2 * kRange * kKnotsPerUnit) + 2;

  NormalTable() {
    const double h = 1.0 / kKnotsPerUnit;
    for (int i = 0; i + 1 < kKnots; ++i) {
      const double x0 = -kRange + i * h, x1 = x0 + h;
      const double c0 = Cdf(x0), c1 = Cdf(x1), p0 = Pdf(x0), p1 = Pdf(x1);
      // Hermite basis on [0, 1]: h00 = 2f^3 - 3f^2 + 1, h10 = f^3 - 2f^2 + f,
      // h01 = -2f^3 + 3f^2, h11 = f^3 - f^2; slopes scaled by h.
      auto cubic = [](double v0, double d0, double v1, double d1) {
        return std::array<double, 4>{v0, d0, -3 * v0 - 2 * d0 + 3 * v1 - d1, 2 * v0 + d0 - 2 * v1 + d1};
      };
      const std::array<double, 4> cdf = cubic(c0, h * p0, c1, h * p1);
      const std::array<double, 4> pdf = cubic(p0, -h * x0 * p0, p1, -h * x1 * p1);
      for (int k = 0; k < 4; ++k) {
        intervals_[i].cdf[k] = cdf[k];
        intervals_[i].pdf[k] = pdf[k];
      }
    }
  }

  CdfPdf operator()(double x) const {
    if (!(x > -kRange)) return {0.0, 0.0};
    if (!(x < kRange)) return {1.0, 0.0};
    const double t = (x + kRange) * kKnotsPerUnit;
    const int i = static_cast<int>(t);
    const double f = t - i;
    const Interval& c = intervals_[i];
    return {c.cdf[0] + f * (c.cdf[1] + f * (c.cdf[2] + f * c.cdf[3])),
            c.pdf[0] + f * (c.pdf[1] + f * (c.pdf[2] + f * c.pdf[3]))};
  }

 private:
  static double Cdf(double x) { return 0.5 * std::erfc(-x * M_SQRT1_2); }
  static double Pdf(double x) { return 0.3989422804014327 * std::exp(-0.5 * x * x); }
  struct alignas(64) Interval {
    double cdf[4];  // coefficients of 1, f, f^2, f^3
    double pdf[4];
  };
  std::array<Interval, kKnots - 1> intervals_{};
};
const NormalTable kNormalTable;  // built at load time, read-only after: thread-safe
inline CdfPdf Normal(double x) { return kNormalTable(x); }
double NormalCdf(double x) { return Normal(x).cdf; }

// The rows of modules behind the border that the model includes (see EdgeModel).
constexpr int kRowsBehind = 2;

// A blurred step further than this many sigmas from a pixel is taken as
// fully on or off there: Phi(-5) = 3e-7, 1e-4 grey levels at 200 of
// contrast. (6 sigma cost ~10 % more time for the same corners to 1e-4 px.)
constexpr double kReachSigmas = 5.0;

// Below this shear the rows' blur is taken as separable (see ShearTerms).
constexpr double kMinShear = 0.01;

// The bivariate normal's CDF with correlation rho, less the product of its
// marginals, over phi(x) phi(y), by the tetrachoric series to rho^4:
// Phi2(x, y; rho) = Phi(x) Phi(y) + phi(x) phi(y) q, q = rho + rho^2 xy/2 +
// rho^3 He2(x) He2(y)/6 + rho^4 He3(x) He3(y)/24 (He: Hermite
// polynomials); dq_dy its derivative in y.
struct Tetrachoric {
  double q = 0.0;
  double dq_dy = 0.0;
};
Tetrachoric TetrachoricSeries(double x, double y, double rho) {
  const double rho2 = rho * rho, rho3 = rho2 * rho, rho4 = rho2 * rho2;
  const double he2x = x * x - 1.0, he2y = y * y - 1.0, he3x = x * x * x - 3.0 * x, he3y = y * y * y - 3.0 * y;
  return {rho + rho2 * x * y / 2 + rho3 * he2x * he2y / 6 + rho4 * he3x * he3y / 24,
          rho2 * x / 2 + rho3 * he2x * 2 * y / 6 + rho4 * he3x * (3 * y * y - 3) / 24};
}

// One pixel of the band around an edge.
struct BandPixel {
  Eigen::Vector2d position;  // pixel centre, image coordinates
  double value = 0.0;        // grey level
  double u = 0.0;            // position along the edge, modules from its start
  double inner_px = 0.0;     // the border's width (one module) across the edge here, px
  double along_px = 0.0;     // one module along the edge here, px
  // Cosine between the edge's normal and the module boundaries' normal
  // (grad u): 0 where they meet the edge at right angles (see ShearTerms).
  double shear = 0.0;
  double beyond_prev = -1e9;  // signed distances outside the adjacent edges' lines, px
  double beyond_next = -1e9;
  // Signed distance outside the white ring's outer line (kRingModules
  // outside the edge), px: from the pass's start, fixed during the fit.
  double beyond_ring = -1e9;
  // Per row behind the border: how much of the outside's shade its modules
  // put here, blurred along the edge (EdgeModel::Shade), and the blur it was
  // computed for (0: not yet).
  std::array<double, kRowsBehind> shade{};
  std::array<double, kRowsBehind> shade_sigma{};
};

// The edge's parameters: outward normal at angle theta, n . x = rho; grey
// levels of the border and of the outside (the white ring); blur sigma in
// px; the mean grey level beyond the ring.
struct EdgeParams {
  double theta = 0.0;
  double rho = 0.0;
  double border = 0.0;
  double outside = 0.0;
  double sigma = 0.8;  // start: a typical lens blur plus the pixel's own width
  double beyond = 0.0;
};
constexpr int kParams = 6;
using ParamVector = Eigen::Matrix<double, kParams, 1>;

// How much white a tag is known to have round its border: one module, what
// libapriltag's official images have printed edge to edge. Beyond it lies
// anything (the surface's texture, another tag, the sheet's edge, or more
// white paper): the model gives it a level of its own (EdgeModel).
constexpr double kRingModules = 1.0;

// Model of the grey level at a band pixel: border + (outside - border) * g,
// g = Phi(d / sigma) for the outer step (d: signed distance outside the
// edge) plus the modules of the kRows rows behind the border (row r at
// depths r+1 to r+2 modules) that have the outside's shade, each blurred
// across and along the edge (a separable Gaussian of a rectangle is a product
// of two blurred steps), and near the band's ends the adjacent edges' steps.
// sigma is the optical blur and the pixel's own area together: the exact
// response of a square pixel (a trapezoid across the edge convolved with the
// Gaussian) measured no better on 3 px modules, at 2-3x the cost.
//
// Where the bias of the first version (+0.01 px outward on 24 px tags tilted
// up to 50 degrees, +0.03 at 70) came from, measured noise-free: the border's
// depth across the edge was taken as the slanted length of one module
// "inward", longer than the perpendicular one under perspective (most of
// it); the module boundaries along the edge are slanted too, so a module's
// blur along the edge is 1/|grad u| px, not the module's length; the second
// row behind the border reaches the band at blur >= 1 px (+0.004 px at 1.2
// px blur without it); and the adjacent edges' blur at the band's ends pulled
// the edge inward (-0.016 px at 1.5 px blur).
class EdgeModel {
 public:
  static constexpr int kRows = kRowsBehind;
  // rows[r][k]: module k of row r + 1 behind the border has the outside's shade.
  explicit EdgeModel(const std::array<std::vector<bool>, kRows>& rows) {
    for (int r = 0; r < kRows; ++r) rows_[r] = RowSteps(rows[r]);
  }

  // Value and derivatives with respect to (theta, rho, border, outside,
  // sigma); `normal` is (cos theta, sin theta), computed once per pass;
  // `shade_sigma`: the blur for the row shades (see Shade).
  // `adjacent_shear`: the cosines between this edge's normal and the
  // previous and next edges' (0 at right-angled corners).
  double Evaluate(BandPixel& p, const EdgeParams& e, const Eigen::Vector2d& normal, double shade_sigma,
                  const std::array<double, 2>& adjacent_shear, ParamVector* jacobian) const {
    const Eigen::Vector2d tangent(-normal.y(), normal.x());
    const double d = normal.dot(p.position) - e.rho;
    // Multiplications by 1/sigma, not ~10 divisions per pixel.
    const double inv_s = 1.0 / e.sigma;
    Shading s;
    AddBorderAndCorners(p, d * inv_s, inv_s, adjacent_shear, &s);
    AddRowsBehind(p, d, inv_s, shade_sigma, &s);
    // Beyond the white ring: its own level, blurred in across the ring's
    // outer line. That line is fixed during the fit, and the term leaves the
    // line's and the blur's derivatives alone: what lies beyond (texture,
    // a sheet's edge cut anywhere) must not place the edge, only keep it out
    // of the white level.
    const double c = p.beyond_ring * inv_s;
    const double ring = c > -kReachSigmas ? Normal(c).cdf : 0.0;
    const double contrast = e.outside - e.border;
    if (jacobian != nullptr) {
      (*jacobian)(0) = contrast * s.dg_dd * tangent.dot(p.position);
      (*jacobian)(1) = -contrast * s.dg_dd;
      (*jacobian)(2) = 1.0 - s.g;
      (*jacobian)(3) = s.g - ring;
      (*jacobian)(4) = contrast * s.dg_ds;
      (*jacobian)(5) = ring;
    }
    return e.border + contrast * s.g + (e.beyond - e.outside) * ring;
  }

  // The pixel's shade from row r for blur `sigma`. It changes little with
  // the blur, so the fit computes it once per pass, not per evaluation (and
  // treats it as a constant in the Jacobian), and only where the row's blur
  // reaches the pixel: computed on first use, not for the whole band (a
  // third to three quarters of the pixels, the more the bigger the tag,
  // never need it: 2-8 % of the refinement's time saved).
  // (A third of the fit's time went here: hence each row's boundaries where
  // the shade changes are listed once, not searched per pixel.)
  double Shade(int r, double sigma, BandPixel* p) const {
    if (p->shade_sigma[r] != sigma) {
      p->shade[r] = RowShade(rows_[r], p->u, sigma / p->along_px);
      p->shade_sigma[r] = sigma;
    }
    return p->shade[r];
  }

  // g, the outside's share of a pixel's grey level, and its derivatives in
  // the edge's offset d and in the blur.
  struct Shading {
    double g = 0.0, dg_dd = 0.0, dg_ds = 0.0;
  };

  // The outer step at a = d / sigma. Near the band's ends the adjacent
  // edges' outside shade reaches in too: the border's shade is that of the
  // blurred corner region, the product of the three half-planes' blurred
  // indicators (exact for a right-angled corner, since a Gaussian is
  // separable along any pair of orthogonal axes); where the corner is not a
  // right angle the two half-planes' blurs are correlated, and each pair
  // gets the tetrachoric correction (see ShearTerms).
  static void AddBorderAndCorners(const BandPixel& p, double a, double inv_s, const std::array<double, 2>& adjacent_shear,
                                  Shading* s) {
    double inside_adjacent = 1.0, dinside_ds = 0.0;
    for (double beyond : {p.beyond_prev, p.beyond_next}) {
      const double c = beyond * inv_s;
      if (c < -kReachSigmas) continue;
      const CdfPdf n = Normal(-c);
      dinside_ds = dinside_ds * n.cdf + inside_adjacent * n.pdf * c * inv_s;
      inside_adjacent *= n.cdf;
    }
    const CdfPdf outer = Normal(-a);
    s->g += 1.0 - outer.cdf * inside_adjacent;
    s->dg_dd += outer.pdf * inv_s * inside_adjacent;
    s->dg_ds += -a * outer.pdf * inv_s * inside_adjacent - outer.cdf * dinside_ds;
    const std::array<double, 2> beyond = {p.beyond_prev, p.beyond_next};
    for (int k = 0; k < 2; ++k) {
      const double rho = adjacent_shear[k];
      const double c = beyond[k] * inv_s;
      if (c < -kReachSigmas || std::abs(rho) <= kMinShear) continue;
      const double other_c = beyond[1 - k] * inv_s;
      const double other = other_c < -kReachSigmas ? 1.0 : Normal(-other_c).cdf;
      const Tetrachoric t = TetrachoricSeries(c, a, rho);
      const double phi_c = Normal(c).pdf;
      s->g -= outer.pdf * phi_c * t.q * other;
      s->dg_dd -= outer.pdf * phi_c * (t.dq_dy - a * t.q) * other * inv_s;
    }
  }

  // The modules of the rows behind the border that have the outside's
  // shade, each blurred across and along the edge.
  void AddRowsBehind(BandPixel& p, double d, double inv_s, double shade_sigma, Shading* s) const {
    // Row r's inner boundary is row r + 1's outer one: its look-up is shared
    // (one of ~5 per pixel saved where both rows show).
    CdfPdf shared{};
    int shared_row = -1;
    for (int r = 0; r < kRows; ++r) {
      const double b0 = (d + (r + 1) * p.inner_px) * inv_s;  // the row's outer and inner boundaries
      const double b1 = (d + (r + 2) * p.inner_px) * inv_s;
      if (b0 > kReachSigmas || b1 < -kReachSigmas) continue;  // the row's blur does not reach this pixel
      const double shade = Shade(r, shade_sigma, &p);
      if (shade == 0.0) continue;
      const CdfPdf n0 = shared_row == r ? shared : Normal(-b0), n1 = Normal(-b1);
      shared = n1;
      shared_row = r + 1;
      s->g += shade * (n0.cdf - n1.cdf);
      s->dg_dd += shade * (n1.pdf - n0.pdf) * inv_s;
      s->dg_ds += shade * (b0 * n0.pdf - b1 * n1.pdf) * inv_s;
      if (std::abs(p.shear) > kMinShear) {
        double value = 0.0, slope = 0.0;
        ShearTerms(r, shade_sigma / p.along_px, p, b0, n0.pdf, b1, n1.pdf, &value, &slope);
        s->g += value;
        s->dg_dd += slope * inv_s;
      }
    }
  }

  // Row r's cells are blurred above as (blurred along) x (blurred across),
  // exact only where the module boundaries meet the edge at right angles.
  // On a tag tilted about an axis that is not along its edges they are
  // slanted (shear, the cosine rho between the two normals): the blur of a
  // cell is then the bivariate normal probability of a parallelogram,
  // whose difference from the product, per shade step j and across
  // boundary b, is -phi(a) phi(b) TetrachoricSeries(a, b, rho), with
  // a = (u - j) / sigma along and b the boundary's blurred distance (the
  // minus: the cell lies beyond its step in u but short of its boundary in
  // d, one variable taken with its sign flipped, which flips every term of
  // the series). Without
  // it, corners on 24 px tags tilted 50-60 degrees about a diagonal came out
  // 0.009-0.022 px inward at 1 px blur, noise-free (about an edge: 0.001).
  // `value`: the term to add to g; `slope`: its derivative in b (the
  // across distance), to be divided by sigma.
  void ShearTerms(int r, double sigma_modules, const BandPixel& p, double b0, double pdf0, double b1, double pdf1,
                  double* value, double* slope) const {
    const double reach = kReachSigmas * sigma_modules, inv_sigma = 1.0 / sigma_modules;
    for (const auto& [j, step] : rows_[r].steps) {
      if (j < p.u - reach) continue;
      if (j > p.u + reach) break;
      const double a = (p.u - j) * inv_sigma;
      const double phi_a = Normal(a).pdf;
      for (const auto& [b, pdf, sign] : {std::tuple<double, double, double>{b0, pdf0, 1.0}, {b1, pdf1, -1.0}}) {
        const Tetrachoric t = TetrachoricSeries(a, b, p.shear);
        *value -= sign * step * phi_a * pdf * t.q;
        *slope -= sign * step * phi_a * pdf * (t.dq_dy - b * t.q);
      }
    }
  }


 private:
  // A row's modules (1: the outside's shade) and the boundaries j (between
  // modules j - 1 and j, 0..n) where the shade steps, in order.
  struct Row {
    std::vector<double> module;
    std::vector<std::pair<int, double>> steps;  // boundary, step
  };
  static Row RowSteps(const std::vector<bool>& like_outside) {
    Row row;
    const int n = static_cast<int>(like_outside.size());
    auto at = [&](int k) { return k >= 0 && k < n && like_outside[k] ? 1.0 : 0.0; };
    for (int k = 0; k < n; ++k) row.module.push_back(at(k));
    for (int j = 0; j <= n; ++j) {
      if (at(j) != at(j - 1)) row.steps.emplace_back(j, at(j) - at(j - 1));
    }
    return row;
  }

  // Blurred indicator, along the edge, of a row's outside-shade modules:
  // the module's own shade at u, corrected at the boundaries within the
  // blur's reach (kReachSigmas) where the shade changes.
  static double RowShade(const Row& row, double u, double sigma_modules) {
    const int k = static_cast<int>(std::floor(u));
    double shade = k >= 0 && k < static_cast<int>(row.module.size()) ? row.module[k] : 0.0;
    const double reach = kReachSigmas * sigma_modules, inv_sigma = 1.0 / sigma_modules;
    for (const auto& [j, step] : row.steps) {
      if (j < u - reach) continue;
      if (j > u + reach) break;
      shade += step * (NormalCdf((u - j) * inv_sigma) - (u >= j ? 1.0 : 0.0));
    }
    return shade;
  }

  std::array<Row, kRows> rows_;
};

// Gauss-Newton on one edge's band (positions relative to the band's
// centroid, so that the angle and the offset are decoupled), one step at a
// time, each a pass over the band's pixels. A step that raised the cost,
// seen at the next step, is taken back and halved; costs compare only while
// the model stays the same (the row shades' blur, the adjacent lines).
//
// The row shades are recomputed whenever the blur has changed by more than
// kShadeTolerance. A stale shade is not a small error: blurred along the
// edge with too little blur, a row's white modules come out brighter and
// its black ones darker, an error that is anti-correlated with the shade
// itself and so pulls the edge one way. With shades held at a blur 7 %
// (the first pass's old tolerance, 10 %) or 2 % (the second's) off, corners
// came out 0.05 and 0.013 px inward on 28 px tags at 1.5 px blur,
// noise-free (docs/detection.md, "Stale row shades").
constexpr double kShadeTolerance = 1e-3;

class EdgeFit {
 public:
  EdgeFit(const EdgeModel* model, std::vector<BandPixel> band, const Eigen::Vector2d& origin, double half_length)
      : model_(model), band_(std::move(band)), origin_(origin), half_length_(half_length), jr_(band_.size()) {}

  const std::vector<BandPixel>& band() const { return band_; }
  const Eigen::Vector2d& origin() const { return origin_; }

  // The band's distances outside the adjacent edges' lines (image
  // coordinates), where they have moved since the last call.
  void SetAdjacentLines(const EdgeLine& previous, const EdgeLine& next) {
    if (Same(previous, previous_line_) && Same(next, next_line_)) return;
    previous_line_ = previous;
    next_line_ = next;
    for (BandPixel& p : band_) {
      const Eigen::Vector2d x = p.position + origin_;
      p.beyond_prev = previous.normal.dot(x) - previous.offset;
      p.beyond_next = next.normal.dot(x) - next.offset;
    }
    previous_cost_ = std::numeric_limits<double>::infinity();  // a different model: costs do not compare
  }

  // One step from `params`; false when the system has no finite solution.
  // `moved_px`: how far the step moved the line's ends.
  bool Step(EdgeParams* params, double* moved_px);

  // The covariance of the line's angle and offset (theta, rho) where the
  // last accepted step started: the inverse normal matrix times the
  // residuals' variance (sum r^2 over pixels minus parameters), so the
  // image's noise and what the model misses both count. Zero before a step.
  Eigen::Matrix2d LineCovariance() const;

 private:
  static bool Same(const EdgeLine& a, const EdgeLine& b) { return a.normal == b.normal && a.offset == b.offset; }

  const EdgeModel* model_;
  std::vector<BandPixel> band_;
  Eigen::Vector2d origin_;
  double half_length_;
  std::vector<std::array<double, kParams + 1>> jr_;  // per pixel: the Jacobian row and the residual
  EdgeLine previous_line_, next_line_;
  double shade_sigma_ = -1.0;  // the row shades' blur; < 0: not yet set
  EdgeParams previous_;
  ParamVector last_step_ = ParamVector::Zero();
  double previous_cost_ = std::numeric_limits<double>::infinity();
  Eigen::Matrix<double, kParams, kParams> accepted_normal_ = Eigen::Matrix<double, kParams, kParams>::Zero();
};

Eigen::Matrix2d EdgeFit::LineCovariance() const {
  const double dof = static_cast<double>(band_.size()) - kParams;
  if (!(dof > 0) || !std::isfinite(previous_cost_) || accepted_normal_.isZero()) return Eigen::Matrix2d::Zero();
  const Eigen::LDLT<Eigen::Matrix<double, kParams, kParams>> ldlt(accepted_normal_);
  if (ldlt.info() != Eigen::Success) return Eigen::Matrix2d::Zero();
  Eigen::Matrix<double, kParams, 2> unit = Eigen::Matrix<double, kParams, 2>::Zero();
  unit(0, 0) = unit(1, 1) = 1.0;  // theta, rho
  const Eigen::Matrix<double, kParams, 2> columns = ldlt.solve(unit);
  const Eigen::Matrix2d covariance = previous_cost_ / dof * columns.topRows<2>();
  return covariance.allFinite() ? Eigen::Matrix2d(0.5 * (covariance + covariance.transpose())) : Eigen::Matrix2d::Zero();
}

bool EdgeFit::Step(EdgeParams* params, double* moved_px) {
  constexpr int P = kParams;
  using Vector = ParamVector;
  if (shade_sigma_ < 0.0 || std::abs(params->sigma - shade_sigma_) > kShadeTolerance * shade_sigma_) {
    shade_sigma_ = params->sigma;
    previous_cost_ = std::numeric_limits<double>::infinity();  // a different model: costs do not compare
  }
  Eigen::Matrix<double, P, P> normal_matrix = Eigen::Matrix<double, P, P>::Zero();
  Vector gradient = Vector::Zero();
  ParamVector j;
  double cost = 0.0;
  const Eigen::Vector2d normal(std::cos(params->theta), std::sin(params->theta));
  // The normal matrix's 15 upper-triangle entries in plain doubles,
  // mirrored once per step: Eigen's fixed-size outer product (itself far
  // cheaper than its rankUpdate) summed all 25 (~1-2 % saved).
  std::array<double, P * (P + 1) / 2> upper{};
  // A local copy: the loop's stores (shades, jr) might alias *params, which
  // kept 1/sigma from being hoisted out of it (~2-3 % saved).
  const EdgeParams at = *params;
  const std::array<double, 2> adjacent_shear = {normal.dot(previous_line_.normal), normal.dot(next_line_.normal)};
  // Two loops, the model's and then the sums: the model's long chain of
  // dependent look-ups overlaps better across pixels without the 21 sums
  // in the same loop body (~3 % saved).
  for (size_t i = 0; i < band_.size(); ++i) {
    BandPixel& p = band_[i];
    const double r = model_->Evaluate(p, at, normal, shade_sigma_, adjacent_shear, &j) - p.value;
    for (int a = 0; a < P; ++a) jr_[i][a] = j(a);
    jr_[i][P] = r;
  }
  for (const std::array<double, P + 1>& e : jr_) {
    for (int a = 0, k = 0; a < P; ++a) {
      for (int b = a; b < P; ++b) upper[k++] += e[a] * e[b];
    }
    for (int a = 0; a < P; ++a) gradient(a) += e[a] * e[P];
    cost += e[P] * e[P];
  }
  for (int a = 0, k = 0; a < P; ++a) {
    for (int b = a; b < P; ++b) normal_matrix(a, b) = normal_matrix(b, a) = upper[k++];
  }
  // The level beyond the ring is seen only by the band's outermost pixels,
  // and hardly at all where the ring is many pixels wide: damping its step
  // (as if a thousandth of the band saw it fully) keeps the system regular
  // there and leaves the minimum where it is.
  normal_matrix(P - 1, P - 1) += 1e-3 * static_cast<double>(band_.size());
  Vector step;
  if (cost > previous_cost_) {
    // Overshot: back to the previous point, half the step.
    *params = previous_;
    step = 0.5 * last_step_;
  } else {
    normal_matrix.diagonal() *= 1.0 + 1e-6;
    step = normal_matrix.ldlt().solve(-gradient);
    if (!step.allFinite()) return false;
    previous_ = *params;
    previous_cost_ = cost;
    accepted_normal_ = normal_matrix;
  }
  // A start off by up to a pixel needs no bigger steps than this.
  step(1) = std::clamp(step(1), -0.5, 0.5);
  step(4) = std::clamp(step(4), -0.3, 0.3);
  last_step_ = step;
  params->theta += step(0);
  params->rho += step(1);
  params->border += step(2);
  params->outside += step(3);
  params->sigma = std::clamp(params->sigma + step(4), 0.2, 10.0);
  params->beyond += step(P - 1);
  *moved_px = std::abs(step(1)) + std::abs(step(0)) * half_length_;
  return true;
}

// Image pixels to undistorted pixel coordinates (the same K, no
// distortion) around one tag, where edges are straight: a polynomial
// fitted to exact undistortion on a grid over the tag's neighbourhood (exact
// undistortion is iterative and ~100x dearer per pixel; over a tag's few
// dozen pixels a quartic follows it to below 1e-3 px, checked between the
// grid's points). The grid's pairs come from the lens's forward model.
class LocalUndistortion {
 public:
  static std::optional<LocalUndistortion> Fit(const CameraModel& camera, const Eigen::Vector2d& low,
                                              const Eigen::Vector2d& high) {
    LocalUndistortion map;
    map.camera_ = &camera;
    map.center_ = 0.5 * (low + high);
    map.scale_ = std::max(1.0, 0.5 * (high - low).maxCoeff());
    // The grid is laid in undistorted pixels and sent through the lens
    // (closed form): exact undistortion is iterative, and was two thirds of
    // the cost of this fit when the grid was undistorted point by point.
    // Only the region's outline is undistorted, to place the grid over it.
    std::vector<Eigen::Vector2d> outline;
    for (int j = 0; j <= 2; ++j) {
      for (int i = 0; i <= 2; ++i) {
        if (i == 1 && j == 1) continue;
        outline.push_back(low + Eigen::Vector2d(0.5 * i * (high - low).x(), 0.5 * j * (high - low).y()));
      }
    }
    Eigen::Vector2d ulow(1e18, 1e18), uhigh(-1e18, -1e18);
    for (const Eigen::Vector2d& n : camera.PixelsToNormalized(outline)) {
      const Eigen::Vector2d u = map.ToPixel(n);
      if (!u.allFinite()) return std::nullopt;
      ulow = ulow.cwiseMin(u);
      uhigh = uhigh.cwiseMax(u);
    }
    const Eigen::Vector2d pad = 0.05 * (uhigh - ulow) + Eigen::Vector2d(0.5, 0.5);  // the outline's edges bow between its points
    ulow -= pad;
    uhigh += pad;
    constexpr int kGrid = 7;  // fit points per axis; the check points lie between them
    Eigen::MatrixXd a(kGrid * kGrid, kTerms);
    Eigen::MatrixXd b(kGrid * kGrid, 2);
    std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> checks;  // image pixel, undistorted pixel
    int row = 0;
    for (int j = 0; j < 2 * kGrid - 1; ++j) {
      for (int i = 0; i < 2 * kGrid - 1; ++i) {
        const Eigen::Vector2d u = ulow + Eigen::Vector2d(i * (uhigh - ulow).x(), j * (uhigh - ulow).y()) / (2 * kGrid - 2);
        const Eigen::Vector2d d = map.Distort(u);
        if (!d.allFinite()) return std::nullopt;
        if (i % 2 != 0 || j % 2 != 0) {
          checks.emplace_back(d, u);
          continue;
        }
        a.row(row) = map.Monomials(d).transpose();
        b.row(row) = u.transpose();
        ++row;
      }
    }
    const Eigen::MatrixXd coefficients = a.colPivHouseholderQr().solve(b);
    map.coefficients_ = coefficients;
    for (const auto& [d, u] : checks) {
      if (!((map(d) - u).norm() < 1e-3)) return std::nullopt;
    }
    return map;
  }

  Eigen::Vector2d operator()(const Eigen::Vector2d& pixel) const {
    return coefficients_.transpose() * Monomials(pixel);
  }
  // Exact, for the few corner points.
  Eigen::Vector2d Undistort(const Eigen::Vector2d& pixel) const {
    return ToPixel(camera_->PixelToNormalized(pixel));
  }
  Eigen::Vector2d Distort(const Eigen::Vector2d& undistorted) const {
    return camera_->Project(Eigen::Vector3d((undistorted.x() - camera_->cx) / camera_->fx,
                                            (undistorted.y() - camera_->cy) / camera_->fy, 1.0));
  }

 private:
  static constexpr int kTerms = 15;  // all monomials up to degree 4
  Eigen::Matrix<double, kTerms, 1> Monomials(const Eigen::Vector2d& pixel) const {
    const double x = (pixel.x() - center_.x()) / scale_, y = (pixel.y() - center_.y()) / scale_;
    const double x2 = x * x, y2 = y * y;
    Eigen::Matrix<double, kTerms, 1> m;
    m << 1, x, y, x2, x * y, y2, x2 * x, x2 * y, x * y2, y2 * y, x2 * x2, x2 * x * y, x2 * y2, x * y2 * y, y2 * y2;
    return m;
  }
  Eigen::Vector2d ToPixel(const Eigen::Vector2d& normalized) const {
    return {camera_->fx * normalized.x() + camera_->cx, camera_->fy * normalized.y() + camera_->cy};
  }

  const CameraModel* camera_ = nullptr;
  Eigen::Vector2d center_;
  double scale_ = 1.0;
  Eigen::Matrix<double, kTerms, 2> coefficients_;
};

// How far edge i's band reaches across the edge, in modules. Outside: up
// to the white ring's outer line, never beyond it: what lies there is
// unknown (a band reaching 2 modules out measured +0.015 px at margin 2,
// where it met the paper's edge; 0.8 of a module, the old band, left the
// ring's level to fewer pixels: bias -0.002 to -0.004 px). Inside: the
// border and half the row behind it.
constexpr double kBandOutside = kRingModules, kBandInside = 1.5;

// A point of the tag's square (modules) in the image.
Eigen::Vector2d SquareToImage(const Eigen::Matrix3d& image_from_square, const Eigen::Vector2d& q) {
  return (image_from_square * q.homogeneous()).hnormalized().eval();
}

// The image line through two points of the square, its normal pointing away
// from the square's centre.
EdgeLine ImageLineThrough(const Eigen::Matrix3d& image_from_square, const Eigen::Vector2d& center,
                          const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d pa = SquareToImage(image_from_square, a), pb = SquareToImage(image_from_square, b);
  Eigen::Vector2d normal = Eigen::Vector2d(-(pb - pa).y(), (pb - pa).x()).normalized();
  if (normal.dot(pa - SquareToImage(image_from_square, center)) < 0.0) normal = -normal;
  return EdgeLine{normal, normal.dot(pa)};
}

// What the scan of edge i's band needs at each pixel: the edge's axes in the
// square (modules), the lines a pixel's depths are measured from, and the
// homography back into the square.
struct BandScan {
  int n = 0;                         // modules across the square
  double end_margin_modules = 0.0;   // kept clear of the corners
  const LocalUndistortion* undistortion = nullptr;
  bool half = false;                 // one checkerboard colour only
  Eigen::Vector2d start;             // the edge's first corner
  Eigen::Vector2d along;             // one module along the edge
  Eigen::Vector2d inward;            // one module across it, towards the centre
  EdgeLine outer_line;               // the edge
  EdgeLine inner_line;               // the border's inner edge, one module in
  EdgeLine ring_line;                // the white ring's outer line, kRingModules out
  Eigen::Matrix3d square_from_image;
  // `along` through the homography's linear part: grad u's constant part
  // (see AddBandPixel).
  Eigen::Vector2d along_row;
};

BandScan BandScanOf(const Eigen::Matrix3d& image_from_square, int n, int i, double end_margin_modules,
                    const LocalUndistortion* undistortion, bool half) {
  BandScan scan;
  scan.n = n;
  scan.end_margin_modules = end_margin_modules;
  scan.undistortion = undistortion;
  scan.half = half;
  scan.square_from_image = image_from_square.inverse();
  const QuadCorners square = CornerSquareCorners(n);
  const Eigen::Vector2d start = square[i];
  const Eigen::Vector2d along = (square[(i + 1) % 4] - start) / n;  // one module long
  const Eigen::Vector2d center(0.5 * n, 0.5 * n);
  const Eigen::Vector2d inward = (center - 0.5 * (start + square[(i + 1) % 4])) / (0.5 * n);
  scan.start = start;
  scan.along = along;
  scan.inward = inward;
  scan.outer_line = ImageLineThrough(image_from_square, center, start, start + n * along);
  scan.inner_line = ImageLineThrough(image_from_square, center, start + inward, start + n * along + inward);
  scan.ring_line = ImageLineThrough(image_from_square, center, start - kRingModules * inward,
                                    start + n * along - kRingModules * inward);
  const Eigen::Matrix3d& h = scan.square_from_image;
  scan.along_row =
      Eigen::Vector2d(along.x() * h(0, 0) + along.y() * h(1, 0), along.x() * h(0, 1) + along.y() * h(1, 1));
  return scan;
}

// The band's outline in the image (distorted, where its pixels are): the
// image of a rectangle, a convex quadrilateral, corners in order round it.
std::array<Eigen::Vector2d, 4> BandQuad(const Eigen::Matrix3d& image_from_square, const BandScan& scan) {
  std::array<Eigen::Vector2d, 4> quad;
  int k = 0;
  for (double u : {scan.end_margin_modules, scan.n - scan.end_margin_modules}) {
    for (double v : {-kBandOutside, kBandInside}) {
      const Eigen::Vector2d p = SquareToImage(image_from_square, scan.start + u * scan.along + v * scan.inward);
      quad[k++] = scan.undistortion != nullptr ? scan.undistortion->Distort(p) : p;
    }
  }
  std::swap(quad[2], quad[3]);  // around the quadrilateral
  return quad;
}

// The image rows [first, last] the quadrilateral covers, widened by `pad`
// and clipped to the image (last < first: none).
struct RowRange {
  int first = 0;
  int last = -1;
};
RowRange RowsOf(const std::array<Eigen::Vector2d, 4>& quad, double pad, int image_rows) {
  double y_min = 1e18, y_max = -1e18;
  for (const Eigen::Vector2d& p : quad) {
    y_min = std::min(y_min, p.y());
    y_max = std::max(y_max, p.y());
  }
  return {std::max(0, static_cast<int>(std::floor(y_min - pad))),
          std::min(image_rows - 1, static_cast<int>(std::ceil(y_max + pad)))};
}

// Room for the quadrilateral's area and its rows' ends: growing the vector
// copied each pixel ~twice (with the pixels built in place and thinned in
// place, ~2 % of the refinement saved).
size_t BandCapacity(const std::array<Eigen::Vector2d, 4>& quad, bool half, const RowRange& rows, double pad) {
  double area = 0.0;
  for (int e = 0; e < 4; ++e) {
    area += 0.5 * (quad[e].x() * quad[(e + 1) % 4].y() - quad[(e + 1) % 4].x() * quad[e].y());
  }
  return static_cast<size_t>(std::abs(area) / (half ? 2 : 1)) +
         4 * static_cast<size_t>(rows.last - rows.first + 2 + 2 * pad);
}

// Where the quadrilateral meets row y, widened by `pad`: [low, high], empty
// (high < low) where it misses the row.
struct RowSpan {
  double low = 1e18;
  double high = -1e18;
};
RowSpan SpanOfRow(const std::array<Eigen::Vector2d, 4>& quad, int y, double pad) {
  RowSpan span;
  for (int e = 0; e < 4; ++e) {
    const Eigen::Vector2d& a = quad[e];
    const Eigen::Vector2d& b = quad[(e + 1) % 4];
    if (std::abs(a.y() - y) <= pad) {
      span.low = std::min(span.low, a.x());
      span.high = std::max(span.high, a.x());
    }
    if (a.y() == b.y()) continue;
    for (double row_y : {y - pad, y + pad}) {
      const double t = (row_y - a.y()) / (b.y() - a.y());
      if (t < 0.0 || t > 1.0) continue;
      const double x = a.x() + t * (b.x() - a.x());
      span.low = std::min(span.low, x);
      span.high = std::max(span.high, x);
    }
  }
  return span;
}

// The pixel at `pixel` (fit coordinates) appended to the band if it lies in
// it: its place along the edge, the border's depth and a module's length
// there, and its distance outside the white ring.
void AddBandPixel(const BandScan& scan, const Eigen::Vector2d& pixel, uchar value, std::vector<BandPixel>* band) {
  const Eigen::Matrix3d& h = scan.square_from_image;
  const double inv_w = 1.0 / (h(2, 0) * pixel.x() + h(2, 1) * pixel.y() + h(2, 2));
  const Eigen::Vector2d q((h(0, 0) * pixel.x() + h(0, 1) * pixel.y() + h(0, 2)) * inv_w,
                          (h(1, 0) * pixel.x() + h(1, 1) * pixel.y() + h(1, 2)) * inv_w);
  const double u = (q - scan.start).dot(scan.along);
  const double v = (q - scan.start).dot(scan.inward);
  if (u < scan.end_margin_modules || u > scan.n - scan.end_margin_modules || v < -kBandOutside || v > kBandInside) {
    return;
  }
  BandPixel& p = band->emplace_back();
  p.position = pixel;
  p.value = value;
  p.u = u;
  p.beyond_ring = scan.ring_line.normal.dot(pixel) - scan.ring_line.offset;
  // Across-edge depth of the border at this pixel: the difference of
  // its distances to the outer edge line and to the border's inner
  // line (both straight in the image), not the slanted length of one
  // module "inward", which under perspective is longer.
  p.inner_px = (scan.inner_line.normal.dot(pixel) - scan.inner_line.offset) -
               (scan.outer_line.normal.dot(pixel) - scan.outer_line.offset);
  // One module along the edge as the blur sees it: the distance across
  // the (under perspective slanted) boundaries between modules,
  // 1/|grad u|, from the homography's derivative: grad u = (row of the
  // homography along the edge - (q . along) h's last row) / w, with the
  // constant part out of the loop: one division per pixel for q and grad
  // u, not five (with StartLevels' histogram, ~5 % of the refinement).
  const double q_along = q.dot(scan.along);
  const double du_dx = (scan.along_row.x() - q_along * h(2, 0)) * inv_w;
  const double du_dy = (scan.along_row.y() - q_along * h(2, 1)) * inv_w;
  const double grad_u = std::max(1e-9, std::sqrt(du_dx * du_dx + du_dy * du_dy));
  p.along_px = 1.0 / grad_u;
  p.shear = (scan.outer_line.normal.x() * du_dx + scan.outer_line.normal.y() * du_dy) / grad_u;
}

// The band's pixels on image row y (with `half`, those of one checkerboard
// colour), appended to the band.
void ScanBandRow(const cv::Mat& image, int y, const std::array<Eigen::Vector2d, 4>& quad, double pad,
                 const BandScan& scan, std::vector<BandPixel>* band) {
  const RowSpan span = SpanOfRow(quad, y, pad);
  if (span.high < span.low) return;
  const int x0 = std::max(0, static_cast<int>(std::floor(span.low - pad)));
  const int x1 = std::min(image.cols - 1, static_cast<int>(std::ceil(span.high + pad)));
  const uchar* row = image.ptr<uchar>(y);
  const int step = scan.half ? 2 : 1;
  for (int x = scan.half ? x0 + ((x0 + y) & 1) : x0; x <= x1; x += step) {
    const Eigen::Vector2d pixel =
        scan.undistortion != nullptr ? (*scan.undistortion)(Eigen::Vector2d(x, y)) : Eigen::Vector2d(x, y);
    AddBandPixel(scan, pixel, row[x], band);
  }
}

// Positions relative to the band's centroid (see FitEdgeModel), which goes
// to `origin`; an empty band leaves it as it was.
void MoveOriginToCentroid(std::vector<BandPixel>* band, Eigen::Vector2d* origin) {
  if (band->empty()) return;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const BandPixel& p : *band) centroid += p.position;
  centroid /= static_cast<double>(band->size());
  for (BandPixel& p : *band) p.position -= centroid;
  *origin = centroid;
}

// A big tag's edge has thousands of pixels; 400 evenly spread ones (what a
// ~40 px tag has) give the line to ~0.01 px at noise 2 and bound the cost.
void ThinEvenly(std::vector<BandPixel>* band) {
  constexpr size_t kMaxBandPixels = 400;
  if (band->size() <= kMaxBandPixels) return;
  const double stride = static_cast<double>(band->size()) / kMaxBandPixels;
  // In place (i * stride >= i), not into a second vector.
  for (size_t i = 0; i < kMaxBandPixels; ++i) (*band)[i] = (*band)[static_cast<size_t>(i * stride)];
  band->resize(kMaxBandPixels);
}

// The pixels of edge i's band: from the white ring's outer line (one
// module outside the edge) to 1.5 modules inside (the border and half the row behind it), clear of the
// corners. Geometry in undistorted pixels when `undistortion` is given.
// `half`: only the pixels of one checkerboard colour (x + y even), for the
// first pass, whose result only places the second pass's band.
std::vector<BandPixel> CollectBand(const cv::Mat& image, const Eigen::Matrix3d& image_from_square, int n, int i,
                                   double end_margin_modules, const LocalUndistortion* undistortion, bool half,
                                   Eigen::Vector2d* band_origin) {
  const BandScan scan = BandScanOf(image_from_square, n, i, end_margin_modules, undistortion, half);
  // The band is the image of a rectangle: a convex quadrilateral, scanned
  // row by row between its sides (in the distorted image its sides bow by
  // less than the padding).
  const std::array<Eigen::Vector2d, 4> quad = BandQuad(image_from_square, scan);
  const double pad = undistortion != nullptr ? 1.0 : 0.0;
  const RowRange rows = RowsOf(quad, pad, image.rows);
  std::vector<BandPixel> band;
  if (rows.last < rows.first || rows.last - rows.first > 4000) return band;
  band.reserve(BandCapacity(quad, half, rows, pad));
  for (int y = rows.first; y <= rows.last; ++y) ScanBandRow(image, y, quad, pad, scan, &band);
  MoveOriginToCentroid(&band, band_origin);
  ThinEvenly(&band);
  return band;
}

// Which modules of the rows behind edge i have the outside's shade.
std::array<std::vector<bool>, EdgeModel::kRows> RowsBehindEdge(const TagLayout& layout, int i) {
  const int n = layout.modules_across;
  const QuadCorners square = CornerSquareCorners(n);
  const Eigen::Vector2d start = square[i];
  const Eigen::Vector2d along = (square[(i + 1) % 4] - start) / n;
  const Eigen::Vector2d center(0.5 * n, 0.5 * n);
  const Eigen::Vector2d inward = (center - 0.5 * (start + square[(i + 1) % 4])) / (0.5 * n);
  std::array<std::vector<bool>, EdgeModel::kRows> rows;
  for (int r = 0; r < EdgeModel::kRows; ++r) {
    rows[r].assign(n, false);
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector2d q = start + (k + 0.5) * along + (r + 1.5) * inward;
      rows[r][k] = !layout.like_border.empty() &&
                   !layout.LikeBorder(static_cast<int>(std::floor(q.x())), static_cast<int>(std::floor(q.y())));
    }
  }
  return rows;
}

// A fitted line's (theta, rho) covariance (EdgeFit::LineCovariance) and the
// point its rho is measured from (its band's centroid).
struct LineUncertainty {
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
};

// The covariance of `corner`, where lines a and b meet: each line's
// variance across itself there (its offset's, and its angle's times the
// distance along it from its band's centroid) carried through the
// intersection. The bands stay clear of the corners and share no pixels, so
// the two lines' errors are independent.
Eigen::Matrix2d CornerCovariance(const EdgeLine& a, const LineUncertainty& ua, const EdgeLine& b,
                                 const LineUncertainty& ub, const Eigen::Vector2d& corner) {
  auto across_variance = [&](const EdgeLine& line, const LineUncertainty& u) {
    // n . (x - o) = rho, so n . dx = d rho - t d theta, t along the line.
    const double t = Eigen::Vector2d(-line.normal.y(), line.normal.x()).dot(corner - u.origin);
    return u.covariance(1, 1) - 2.0 * t * u.covariance(0, 1) + t * t * u.covariance(0, 0);
  };
  Eigen::Matrix2d normals;
  normals << a.normal.transpose(), b.normal.transpose();
  const Eigen::Matrix2d inverse = normals.inverse();
  const Eigen::Vector2d variances(across_variance(a, ua), across_variance(b, ub));
  return inverse * variances.asDiagonal() * inverse.transpose();
}

bool Intersect(const EdgeLine& a, const EdgeLine& b, Eigen::Vector2d* point) {
  Eigen::Matrix2d normals;
  normals << a.normal.transpose(), b.normal.transpose();
  if (std::abs(normals.determinant()) < 1e-3) return false;  // nearly parallel: no reliable corner
  *point = normals.inverse() * Eigen::Vector2d(a.offset, b.offset);
  return true;
}

// Robust start for the grey levels: low and high percentiles of the band.
void StartLevels(const std::vector<BandPixel>& band, EdgeParams* params) {
  // The values are 8-bit grey levels: the two order statistics from a
  // histogram, not two selections (a sort was 5 % of the fit).
  std::array<int, 256> histogram{};
  for (const BandPixel& p : band) ++histogram[static_cast<uint8_t>(p.value)];
  auto nth_value = [&](size_t k) {  // the k-th smallest value, from 0
    size_t below = 0;
    for (int v = 0; v < 255; ++v) {
      below += static_cast<size_t>(histogram[v]);
      if (below > k) return static_cast<double>(v);
    }
    return 255.0;
  };
  const double low = nth_value(band.size() / 10);
  const double high = nth_value(band.size() * 9 / 10);
  // Which of the two is the border's is decided by the mean value outside.
  double outside_sum = 0.0;
  int outside_count = 0;
  for (const BandPixel& p : band) {
    if (Eigen::Vector2d(std::cos(params->theta), std::sin(params->theta)).dot(p.position) - params->rho > 0.5) {
      outside_sum += p.value;
      ++outside_count;
    }
  }
  const bool bright_outside = outside_count == 0 || outside_sum / outside_count > 0.5 * (low + high);
  params->border = bright_outside ? low : high;
  params->outside = bright_outside ? high : low;
  params->beyond = params->outside;
}

// With lens distortion the edges are straight only in undistorted pixels:
// the fit works there (the corners go back through the distortion after).
// Sets `undistortion` and undistorts `start` when the camera has a lens;
// false when that fails.
bool UndistortStart(const CameraModel* camera, int n, QuadCorners* start,
                    std::optional<LocalUndistortion>* undistortion) {
  if (camera == nullptr || !camera->HasDistortion()) return true;
  Eigen::Vector2d low = (*start)[0], high = (*start)[0];
  for (const Eigen::Vector2d& c : *start) {
    low = low.cwiseMin(c);
    high = high.cwiseMax(c);
  }
  const double reach = 2.0 + 2.5 * (high - low).maxCoeff() / n;  // the band's reach beyond the corners
  *undistortion = LocalUndistortion::Fit(*camera, low.array() - reach, high.array() + reach);
  if (!*undistortion) return false;
  for (Eigen::Vector2d& c : *start) c = (*undistortion)->Undistort(c);
  return std::all_of(start->begin(), start->end(), [](const Eigen::Vector2d& c) { return c.allFinite(); });
}

// Edge i's line through corners i and i+1, its normal pointing out of the quad.
std::array<EdgeLine, 4> StartLines(const QuadCorners& corners) {
  std::array<EdgeLine, 4> lines;
  const Eigen::Vector2d center = 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d from = corners[i], to = corners[(i + 1) % 4];
    Eigen::Vector2d normal = Eigen::Vector2d(-(to - from).y(), (to - from).x()).normalized();
    if (normal.dot(0.5 * (from + to) - center) < 0.0) normal = -normal;
    lines[i] = {normal, normal.dot(from)};
  }
  return lines;
}

// One pass over the four edges: each edge's band sampled from `corners`
// (half of it when `coarse`), its model fitted from the edge's line and
// levels against the adjacent edges' latest lines, then the corners placed
// where the new lines meet. False when an edge cannot be fitted.
bool FitEdgesOnce(const cv::Mat& gray8, int n, bool coarse, double end_margin_modules,
                  const LocalUndistortion* pixel_map, const std::array<EdgeModel, 4>& models, QuadCorners* corners,
                  std::array<EdgeParams, 4>* params, std::array<EdgeLine, 4>* lines,
                  std::array<LineUncertainty, 4>* uncertainty = nullptr) {
  const std::optional<Eigen::Matrix3d> image_from_square = HomographyFrom4(CornerSquareCorners(n), *corners);
  if (!image_from_square) return false;
  // The second pass starts at the first's minimum: a few steps suffice.
  const int max_iterations = coarse ? 5 : 3;
  const double stop_px = coarse ? 0.01 : 1e-4;
  for (int i = 0; i < 4; ++i) {
    Eigen::Vector2d origin = Eigen::Vector2d::Zero();
    std::vector<BandPixel> band =
        CollectBand(gray8, *image_from_square, n, i, end_margin_modules, pixel_map, coarse, &origin);
    if (coarse && band.size() < 24) {  // a tiny tag: half its band is too few pixels
      band = CollectBand(gray8, *image_from_square, n, i, end_margin_modules, pixel_map, false, &origin);
    }
    if (band.size() < 12) return false;
    const double half_length = 0.5 * ((*corners)[(i + 1) % 4] - (*corners)[i]).norm();
    EdgeFit fit(&models[i], std::move(band), origin, half_length);
    fit.SetAdjacentLines((*lines)[(i + 3) % 4], (*lines)[(i + 1) % 4]);
    EdgeParams& e = (*params)[i];
    EdgeLine& line = (*lines)[i];
    e.theta = std::atan2(line.normal.y(), line.normal.x());
    e.rho = line.offset - line.normal.dot(origin);  // relative to the band's centroid
    if (coarse) StartLevels(fit.band(), &e);
    for (int iteration = 0; iteration < max_iterations; ++iteration) {
      double moved = 0.0;
      if (!fit.Step(&e, &moved)) return false;
      if (moved < stop_px) break;
    }
    line.normal = Eigen::Vector2d(std::cos(e.theta), std::sin(e.theta));
    line.offset = e.rho + line.normal.dot(origin);
    if (uncertainty != nullptr) (*uncertainty)[i] = {fit.LineCovariance(), origin};
  }
  for (int i = 0; i < 4; ++i) {
    if (!Intersect((*lines)[(i + 3) % 4], (*lines)[i], &(*corners)[i])) return false;
  }
  return true;
}

}  // namespace

bool RefineCornersByEdgeLines(const cv::Mat& gray8, const TagLayout& layout, QuadCorners* corners,
                              const CameraModel* camera, std::array<Eigen::Matrix2d, 4>* covariances) {
  const int n = layout.modules_across;
  if (gray8.empty() || gray8.type() != CV_8UC1 || n <= 0) return false;
  if (!layout.like_border.empty() && layout.like_border.size() != static_cast<size_t>(n * n)) return false;
  for (const Eigen::Vector2d& c : *corners) {
    if (!c.allFinite()) return false;
  }
  std::optional<LocalUndistortion> undistortion;
  QuadCorners initial = *corners;
  if (!UndistortStart(camera, n, &initial, &undistortion)) return false;
  const LocalUndistortion* pixel_map = undistortion ? &*undistortion : nullptr;
  double mean_side = 0.0;
  for (int i = 0; i < 4; ++i) mean_side += 0.25 * (initial[(i + 1) % 4] - initial[i]).norm();
  const double module_px = mean_side / n;
  // Stay ~1.5 px clear of the corners: the model includes the adjacent
  // edges' blur (EdgeModel), but not the start's error in pass 0.
  const double end_margin_modules = std::clamp(1.5 / module_px, 0.3, 0.25 * n);

  QuadCorners current = initial;
  std::array<EdgeParams, 4> params;                   // levels and blur carry over between passes
  std::array<EdgeLine, 4> lines = StartLines(initial);  // edge i runs from corner i to corner i+1
  // The first pass only needs to come close: it fits half the band's
  // pixels (a checkerboard) and stops at 0.01 px steps (it converges in ~2
  // steps from libapriltag's corners; measured, ~40 % of the fit's time
  // saved). The second pass re-samples the whole band and re-places the row
  // behind the border from the first pass's corners, and always runs: its
  // minimum, on every pixel, is the answer.
  // The edges' models are the same in both passes: built once (their
  // vectors' allocations, ~2 % of the refinement).
  const std::array<EdgeModel, 4> models = {EdgeModel(RowsBehindEdge(layout, 0)), EdgeModel(RowsBehindEdge(layout, 1)),
                                           EdgeModel(RowsBehindEdge(layout, 2)), EdgeModel(RowsBehindEdge(layout, 3))};
  std::array<LineUncertainty, 4> uncertainty;
  for (const bool coarse : {true, false}) {
    if (!FitEdgesOnce(gray8, n, coarse, end_margin_modules, pixel_map, models, &current, &params, &lines,
                      coarse ? nullptr : &uncertainty)) {
      return false;
    }
  }
  // A refinement that moves a corner by more than half a module has locked
  // onto something else; the start is then the better answer.
  const double max_move = std::max(1.5, 0.5 * module_px);
  for (int i = 0; i < 4; ++i) {
    if (!((current[i] - initial[i]).norm() <= max_move)) return false;
  }
  for (int i = 0; i < 4; ++i) (*corners)[i] = pixel_map != nullptr ? pixel_map->Distort(current[i]) : current[i];
  if (covariances != nullptr) {
    for (int i = 0; i < 4; ++i) {
      const int before = (i + 3) % 4;
      Eigen::Matrix2d c = CornerCovariance(lines[before], uncertainty[before], lines[i], uncertainty[i], current[i]);
      if (pixel_map != nullptr) {
        // Fitted in undistorted pixels: carried to the image's through the
        // lens' local Jacobian (central differences over a tenth of a pixel).
        Eigen::Matrix2d jacobian;
        for (int k = 0; k < 2; ++k) {
          const Eigen::Vector2d d = 0.05 * Eigen::Vector2d::Unit(k);
          jacobian.col(k) = (pixel_map->Distort(current[i] + d) - pixel_map->Distort(current[i] - d)) / 0.1;
        }
        c = jacobian * c * jacobian.transpose();
      }
      (*covariances)[i] = c.allFinite() ? c : Eigen::Matrix2d::Zero();
    }
  }
  return true;
}

}  // namespace tagsfm
