#include "blurred_tag_reader.h"

#include <array>
#include <cmath>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace tagsfm::detail {
namespace {

// Coordinates in modules across the tag's black square: x, y in [0, w],
// module (i, j) covers [i, i+1) x [j, j+1); libapriltag's tag frame is
// 2 x / w - 1.
struct ModuleFrame {
  cv::Matx33d image_from_tag;  // homography, libapriltag's tag frame to image pixels
  int w = 0;                   // width_at_border

  Eigen::Vector2d Image(double x, double y) const {
    const cv::Vec3d v = image_from_tag * cv::Vec3d(2.0 * x / w - 1.0, 2.0 * y / w - 1.0, 1.0);
    return {v[0] / v[2], v[1] / v[2]};
  }
};

// The quad's corners in one of the eight orders, as libapriltag lists them
// for tag (-1, 1), (1, 1), (1, -1), (-1, -1).
QuadCorners Ordered(const QuadCorners& q, int winding, int start) {
  QuadCorners corners;
  for (int i = 0; i < 4; ++i) corners[i] = q[winding ? (4 - i + start) % 4 : (i + start) % 4];
  return corners;
}

cv::Matx33d ImageFromTag(const QuadCorners& c) {
  const std::vector<cv::Point2f> tag_pts{{-1, 1}, {1, 1}, {1, -1}, {-1, -1}};
  std::vector<cv::Point2f> image_pts;
  for (const Eigen::Vector2d& p : c) image_pts.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  return cv::getPerspectiveTransform(tag_pts, image_pts);
}

double Phi(double t) { return 0.5 * std::erfc(-t / std::sqrt(2.0)); }

// What a Gaussian of `sigma` modules centred at each sample coordinate of
// one axis sees of the black square [0, w) and of each interior module.
struct AxisCoverage {
  Eigen::VectorXd square;
  Eigen::MatrixXd modules;  // samples x (w-2)
};

AxisCoverage Coverage(const Eigen::VectorXd& coords, int w, double sigma) {
  const int n = w - 2;
  AxisCoverage c;
  c.square.resize(coords.size());
  c.modules.resize(coords.size(), n);
  std::vector<double> edge(static_cast<size_t>(w) + 1);  // at the module boundaries 0..w
  for (Eigen::Index s = 0; s < coords.size(); ++s) {
    for (int k = 0; k <= w; ++k) edge[static_cast<size_t>(k)] = Phi((k - coords[s]) / sigma);
    c.square[s] = edge[static_cast<size_t>(w)] - edge[0];
    for (int i = 0; i < n; ++i) c.modules(s, i) = edge[static_cast<size_t>(i + 2)] - edge[static_cast<size_t>(i + 1)];
  }
  return c;
}

// The levels: black = a0 + a1 x + a2 y, contrast (white - black) =
// c0 + c1 x + c2 y, x and y in modules from the tag's centre.
struct Levels {
  Eigen::Vector3d black = Eigen::Vector3d::Zero();
  Eigen::Vector3d contrast = Eigen::Vector3d::Zero();
};

// A Gaussian blur in tag coordinates (modules): sigma along each tag axis
// and their correlation (a motion along neither axis).
struct Blur {
  double sigma_u = 0.35;
  double sigma_v = 0.35;
  double rho = 0.0;
};

// Samples index as a + c m (a along u, c along v), modules as i + j n:
// Eigen's column-major order, so grids and vectors map onto each other.
class BlurModel {
 public:
  BlurModel(const Eigen::VectorXd& coords, int w, const Blur& blur)
      : coords_(coords), w_(w), n_(w - 2), blur_(blur) {
    const Eigen::Index m = coords.size();
    coverage_.resize(m * m, n_ * n_);
    outside_.resize(m * m);
    Eigen::MatrixXd a(n_ * n_, n_ * n_);  // the normal equations
    if (blur.rho == 0.0) {
      // Separable: the coverage is a product of the axes', the normal
      // equations the Kronecker product of theirs.
      const AxisCoverage cu = Coverage(coords, w, blur.sigma_u), cv = Coverage(coords, w, blur.sigma_v);
      for (Eigen::Index c = 0; c < m; ++c) {
        for (Eigen::Index a = 0; a < m; ++a) {
          const Eigen::Index s = a + c * m;
          outside_[s] = 1.0 - cu.square[a] * cv.square[c];
          for (int j = 0; j < n_; ++j) {
            for (int i = 0; i < n_; ++i) coverage_(s, i + j * n_) = cu.modules(a, i) * cv.modules(c, j);
          }
        }
      }
      const Eigen::MatrixXd gu = cu.modules.transpose() * cu.modules, gv = cv.modules.transpose() * cv.modules;
      for (int j = 0; j < n_; ++j) {
        for (int i = 0; i < n_; ++i) {
          for (int j2 = 0; j2 < n_; ++j2) {
            for (int i2 = 0; i2 < n_; ++i2) a(i + j * n_, i2 + j2 * n_) = gu(i, i2) * gv(j, j2);
          }
        }
      }
    } else {
      CorrelatedCoverage();
      a = coverage_.transpose() * coverage_;
    }
    lambda_ = kRegularisation * a.diagonal().mean();
    a.diagonal().array() += lambda_;
    normal_.compute(a);
  }

  const Blur& blur() const { return blur_; }

  struct Fit {
    Eigen::MatrixXd bits;       // n x n, bits(i, j) of module (i+1, j+1)
    Levels levels;
    Eigen::VectorXd residual;   // grey - model, per sample
    double rms = 1e9;           // grey levels
    double mean_contrast = 0.0;
  };

  // Bits free (regularised towards 0.5) or, with `fixed`, given. `grey`: m x m.
  Fit Solve(const Eigen::MatrixXd& grey_grid, const Eigen::MatrixXd* fixed) const {
    const Eigen::Map<const Eigen::VectorXd> grey(grey_grid.data(), grey_grid.size());
    Fit fit;
    fit.bits = fixed ? *fixed : Eigen::MatrixXd::Constant(n_, n_, 0.5);
    for (int iteration = 0; iteration < 3; ++iteration) {
      fit.levels = FitLevels(grey, Reflectance(fit.bits));
      if (fixed) break;
      fit.bits = SolveBits(grey, fit.levels);
    }
    const Eigen::VectorXd reflectance = Reflectance(fit.bits);
    const Eigen::Index m = coords_.size();
    fit.residual.resize(m * m);
    double contrast = 0.0;
    for (Eigen::Index c = 0; c < m; ++c) {
      for (Eigen::Index a = 0; a < m; ++a) {
        const Eigen::Index s = a + c * m;
        const double k = Contrast(fit.levels, a, c);
        fit.residual[s] = grey[s] - Black(fit.levels, a, c) - k * reflectance[s];
        contrast += k;
      }
    }
    fit.rms = std::sqrt(fit.residual.squaredNorm() / static_cast<double>(m * m));
    fit.mean_contrast = contrast / static_cast<double>(m * m);
    return fit;
  }

 private:
  // The module integrals of a correlated Gaussian: along u in slices of a
  // quarter module (each slice's exact share), along v given u in closed
  // form; modules beyond 4 sigma left out.
  void CorrelatedCoverage() {
    const Eigen::Index m = coords_.size();
    const double su = blur_.sigma_u, sv = blur_.sigma_v, rho = blur_.rho;
    const double slope = rho * sv / su, sv_given_u = sv * std::sqrt(1.0 - rho * rho);
    constexpr int kSlices = 4;
    coverage_.setZero();
    for (Eigen::Index c = 0; c < m; ++c) {
      for (Eigen::Index a = 0; a < m; ++a) {
        const Eigen::Index s = a + c * m;
        const double x = coords_[a], y = coords_[c];
        double square = 0.0;
        const int i0 = std::max(0, static_cast<int>(std::floor(x - 4.0 * su)));
        const int i1 = std::min(w_ - 1, static_cast<int>(std::floor(x + 4.0 * su)));
        for (int i = i0; i <= i1; ++i) {
          for (int t = 0; t < kSlices; ++t) {
            const double lo = i + static_cast<double>(t) / kSlices, hi = lo + 1.0 / kSlices;
            const double mass_u = Phi((hi - x) / su) - Phi((lo - x) / su);
            if (mass_u < 1e-7) continue;
            const double mean_v = y + slope * ((lo + hi) / 2.0 - x);
            const int j0 = std::max(0, static_cast<int>(std::floor(mean_v - 4.0 * sv_given_u)));
            const int j1 = std::min(w_ - 1, static_cast<int>(std::floor(mean_v + 4.0 * sv_given_u)));
            for (int j = j0; j <= j1; ++j) {
              const double mass = mass_u * (Phi((j + 1 - mean_v) / sv_given_u) - Phi((j - mean_v) / sv_given_u));
              square += mass;
              if (i >= 1 && i <= n_ && j >= 1 && j <= n_) coverage_(s, (i - 1) + (j - 1) * n_) += mass;
            }
          }
        }
        outside_[s] = 1.0 - square;
      }
    }
  }

  Eigen::VectorXd Reflectance(const Eigen::MatrixXd& bits) const {
    const Eigen::Map<const Eigen::VectorXd> b(bits.data(), bits.size());
    return outside_ + coverage_ * b;
  }
  double X(Eigen::Index a) const { return coords_[a] - w_ / 2.0; }
  double Black(const Levels& l, Eigen::Index a, Eigen::Index c) const {
    return l.black[0] + l.black[1] * X(a) + l.black[2] * X(c);
  }
  double Contrast(const Levels& l, Eigen::Index a, Eigen::Index c) const {
    return l.contrast[0] + l.contrast[1] * X(a) + l.contrast[2] * X(c);
  }

  // grey = black(x, y) + contrast(x, y) reflectance: linear in the 6 level parameters.
  Levels FitLevels(const Eigen::Ref<const Eigen::VectorXd>& grey, const Eigen::VectorXd& reflectance) const {
    Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
    const Eigen::Index m = coords_.size();
    for (Eigen::Index c = 0; c < m; ++c) {
      for (Eigen::Index a = 0; a < m; ++a) {
        const Eigen::Index s = a + c * m;
        const double r = reflectance[s];
        Eigen::Matrix<double, 6, 1> row;
        row << 1.0, X(a), X(c), r, r * X(a), r * X(c);
        ata.selfadjointView<Eigen::Lower>().rankUpdate(row);
        atb += row * grey[s];
      }
    }
    const Eigen::Matrix<double, 6, 1> p = ata.selfadjointView<Eigen::Lower>().ldlt().solve(atb);
    Levels l;
    l.black = p.head<3>();
    l.contrast = p.tail<3>();
    return l;
  }

  // (grey - black) / contrast - outside = coverage bits, in least squares
  // with a weak pull towards 0.5 (blur near a module's size leaves
  // checkerboard patterns nearly unseen).
  Eigen::MatrixXd SolveBits(const Eigen::Ref<const Eigen::VectorXd>& grey, const Levels& levels) const {
    const Eigen::Index m = coords_.size();
    Eigen::VectorXd y(m * m);
    for (Eigen::Index c = 0; c < m; ++c) {
      for (Eigen::Index a = 0; a < m; ++a) {
        const Eigen::Index s = a + c * m;
        y[s] = (grey[s] - Black(levels, a, c)) / std::max(Contrast(levels, a, c), 1.0) - outside_[s];
      }
    }
    const Eigen::VectorXd rhs = (coverage_.transpose() * y).array() + lambda_ * 0.5;
    const Eigen::VectorXd x = normal_.solve(rhs);
    return Eigen::Map<const Eigen::MatrixXd>(x.data(), n_, n_);
  }
  static constexpr double kRegularisation = 0.01;

  Eigen::VectorXd coords_;
  int w_, n_;
  Blur blur_;
  Eigen::MatrixXd coverage_;  // samples x interior modules
  Eigen::VectorXd outside_;   // per sample, the share of everything but the black square (white)
  double lambda_ = 0.0;
  Eigen::LDLT<Eigen::MatrixXd> normal_;
};

// k x k samples per module over the black square and the white ring around
// it (coordinates -1 .. w+1); none if any falls outside the image.
std::optional<Eigen::MatrixXd> SampleTag(const cv::Mat& g, const QuadCorners& q, int w, const Eigen::VectorXd& coords) {
  const ModuleFrame frame{ImageFromTag(Ordered(q, 0, 0)), w};
  const Eigen::Index m = coords.size();
  Eigen::MatrixXd grey(m, m);
  for (Eigen::Index a = 0; a < m; ++a) {
    for (Eigen::Index c = 0; c < m; ++c) {
      const Eigen::Vector2d p = frame.Image(coords[a], coords[c]);
      const std::optional<double> v = SampleBilinear(g, p.x(), p.y());
      if (!v) return std::nullopt;
      grey(a, c) = *v;
    }
  }
  return grey;
}

// The blur that fits best, from a few Gaussians: alike along both axes
// first, then each axis in turn.
std::optional<BlurModel> SearchBlur(const Eigen::MatrixXd& grey, const Eigen::VectorXd& coords, int w) {
  static constexpr std::array<double, 5> kSigmas{0.2, 0.35, 0.5, 0.7, 0.9};  // modules
  std::optional<BlurModel> best;
  double best_rms = 1e18;
  const auto consider = [&](double u, double v) {
    BlurModel model(coords, w, Blur{u, v, 0.0});
    const double rms = model.Solve(grey, nullptr).rms;
    if (rms < best_rms) {
      best_rms = rms;
      best = std::move(model);
    }
  };
  for (double s : kSigmas) consider(s, s);
  if (!best) return std::nullopt;  // no finite fit: a degenerate patch
  const double iso = best->blur().sigma_u;
  for (double s : kSigmas) {
    if (s != iso) consider(s, iso);
  }
  const double along_u = best->blur().sigma_u;
  for (double s : kSigmas) {
    if (s != iso) consider(along_u, s);
  }
  return best;
}

// Levenberg-Marquardt on the 8 corner coordinates (the bits and levels
// re-solved at each, blur fixed), numerical derivatives: aruco's contour
// corners are up to ~1.5 px off, most of a module at this size.
QuadCorners FitCorners(const cv::Mat& g, const QuadCorners& start, int w, const Eigen::VectorXd& coords,
                       const BlurModel& model, double max_move) {
  const auto residual_at = [&](const QuadCorners& q) -> std::optional<Eigen::VectorXd> {
    const std::optional<Eigen::MatrixXd> grey = SampleTag(g, q, w, coords);
    if (!grey) return std::nullopt;
    return model.Solve(*grey, nullptr).residual;
  };
  QuadCorners q = start;
  std::optional<Eigen::VectorXd> r = residual_at(q);
  if (!r) return start;
  double cost = r->squaredNorm(), mu = 1e-3;
  constexpr double kStep = 0.05;  // px, forward differences
  for (int iteration = 0; iteration < 6; ++iteration) {
    Eigen::MatrixXd jacobian(r->size(), 8);
    for (int p = 0; p < 8; ++p) {
      QuadCorners moved = q;
      moved[p / 2][p % 2] += kStep;
      const std::optional<Eigen::VectorXd> rp = residual_at(moved);
      if (!rp) return q;
      jacobian.col(p) = (*rp - *r) / kStep;
    }
    const Eigen::Matrix<double, 8, 8> jtj = jacobian.transpose() * jacobian;
    const Eigen::Matrix<double, 8, 1> jtr = jacobian.transpose() * *r;
    bool improved = false;
    for (int attempt = 0; attempt < 5 && !improved; ++attempt) {
      Eigen::Matrix<double, 8, 8> damped = jtj;
      damped.diagonal() *= 1.0 + mu;
      const Eigen::Matrix<double, 8, 1> step = damped.ldlt().solve(-jtr);
      if (!step.allFinite()) return q;
      QuadCorners next = q;
      bool within = true;
      for (int c = 0; c < 4; ++c) {
        next[c] += step.segment<2>(2 * c);
        within = within && (next[c] - start[c]).norm() <= max_move;
      }
      const std::optional<Eigen::VectorXd> rn = within ? residual_at(next) : std::nullopt;
      if (rn && rn->squaredNorm() < cost) {
        improved = true;
        q = next;
        r = rn;
        cost = rn->squaredNorm();
        mu = std::max(mu / 10.0, 1e-6);
        if (step.cwiseAbs().maxCoeff() < 0.005) return q;
      } else {
        mu *= 10.0;
      }
    }
    if (!improved) break;
  }
  return q;
}

}  // namespace

bool BlurredReadingSupports(const apriltag_family_t* family) {
  const int w = family->width_at_border;
  if (family->reversed_border || w < 4) return false;
  if (family->nbits != static_cast<uint32_t>((w - 2) * (w - 2))) return false;
  for (uint32_t i = 0; i < family->nbits; ++i) {
    if (family->bit_x[i] < 1 || family->bit_x[i] > static_cast<uint32_t>(w - 2)) return false;
    if (family->bit_y[i] < 1 || family->bit_y[i] > static_cast<uint32_t>(w - 2)) return false;
  }
  return true;
}

namespace {

struct CodeReading {
  QuadReading reading;
  Eigen::MatrixXd bits;  // the code's bits on the grid of order 0
};

// The best code within `max_hamming` of the estimated bits (grid of the
// quad's order 0), over the eight corner orders: module (bit_x, bit_y) of an
// order is a module of the base grid (the orders are the square's symmetries).
std::optional<CodeReading> ReadCode(const Eigen::MatrixXd& estimate, const QuadCorners& q,
                                    const apriltag_family_t* family, int max_hamming) {
  const int w = family->width_at_border, n = w - 2;
  const cv::Matx33d tag_from_image = ImageFromTag(Ordered(q, 0, 0)).inv();
  std::optional<CodeReading> best;
  for (int winding = 0; winding < 2; ++winding) {
    for (int start = 0; start < 4; ++start) {
      const QuadCorners corners = Ordered(q, winding, start);
      const cv::Matx33d base_from_order = tag_from_image * ImageFromTag(corners);
      uint64_t code = 0;
      double margin = 1e9;
      std::vector<std::array<int, 2>> cells(family->nbits);
      for (uint32_t i = 0; i < family->nbits; ++i) {
        const double tx = 2.0 * (family->bit_x[i] + 0.5) / w - 1.0, ty = 2.0 * (family->bit_y[i] + 0.5) / w - 1.0;
        const cv::Vec3d t = base_from_order * cv::Vec3d(tx, ty, 1.0);
        const int bi = static_cast<int>(std::floor((t[0] / t[2] + 1.0) * w / 2.0)) - 1;
        const int bj = static_cast<int>(std::floor((t[1] / t[2] + 1.0) * w / 2.0)) - 1;
        if (bi < 0 || bj < 0 || bi >= n || bj >= n) return std::nullopt;  // not a symmetry: a degenerate quad
        cells[i] = {bi, bj};
        const double b = estimate(bi, bj);
        margin = std::min(margin, std::abs(b - 0.5));
        code = (code << 1) | (b > 0.5 ? 1u : 0u);
      }
      for (uint32_t c = 0; c < family->ncodes; ++c) {
        const int hamming = __builtin_popcountll(family->codes[c] ^ code);
        if (hamming > max_hamming || (best && hamming >= best->reading.hamming)) continue;
        CodeReading r;
        r.reading.id = static_cast<TagId>(c);
        r.reading.hamming = hamming;
        r.reading.margin = margin;
        r.reading.corners = corners;
        r.bits.resize(n, n);
        for (uint32_t i = 0; i < family->nbits; ++i) {
          r.bits(cells[i][0], cells[i][1]) = static_cast<double>((family->codes[c] >> (family->nbits - 1 - i)) & 1u);
        }
        best = std::move(r);
      }
    }
  }
  return best;
}

// One candidate's fit: where its corners are, what the samples there are,
// the blur, the bits and the code they read as.
struct TagFit {
  QuadCorners corners;
  Eigen::MatrixXd grey;
  std::optional<BlurModel> model;
  BlurModel::Fit fit;
  std::optional<CodeReading> code;
};

// Fits with a correlated blur (a motion along neither tag axis) from the
// separable fit `current`; replaces it if that reads with fewer bit errors.
void TryTiltedBlur(const cv::Mat& g, const apriltag_family_t* family, const Eigen::VectorXd& coords,
                   double module_px, int max_hamming, TagFit* current) {
  const int w = family->width_at_border;
  TagFit trial;
  trial.corners = current->corners;
  trial.grey = current->grey;
  double best_rms = current->fit.rms;
  const auto consider = [&](const Blur& blur) {
    BlurModel model(coords, w, blur);
    const double rms = model.Solve(trial.grey, nullptr).rms;
    if (rms < best_rms) {
      best_rms = rms;
      trial.model = std::move(model);
    }
  };
  const Blur base = current->model->blur();
  for (double rho : {-0.6, -0.3, 0.3, 0.6}) consider({base.sigma_u, base.sigma_v, rho});
  // Three rounds of blur and corners (IMG_1409 tag 11: 1, 0 and 0 bit errors
  // after 1, 2 and 3, margin 0.012 after 2 and 0.067 after 3; rho 0.45-0.75).
  for (int round = 0; round < 3 && trial.model; ++round) {
    const Blur found = trial.model->blur();
    for (double scale : {0.8, 1.25}) {
      consider({found.sigma_u * scale, found.sigma_v, found.rho});
      consider({found.sigma_u, found.sigma_v * scale, found.rho});
    }
    for (double rho : {found.rho - 0.15, found.rho + 0.15}) {
      if (std::abs(rho) < 0.9 && std::abs(rho) > 0.01) consider({found.sigma_u, found.sigma_v, rho});
    }
    trial.corners = FitCorners(g, trial.corners, w, coords, *trial.model, 2.0 * module_px);
    std::optional<Eigen::MatrixXd> grey = SampleTag(g, trial.corners, w, coords);
    if (!grey) return;
    trial.grey = std::move(*grey);
    best_rms = trial.model->Solve(trial.grey, nullptr).rms;
  }
  if (!trial.model) return;
  trial.fit = trial.model->Solve(trial.grey, nullptr);
  trial.code = ReadCode(trial.fit.bits, trial.corners, family, max_hamming);
  if (trial.code && (!current->code || trial.code->reading.hamming < current->code->reading.hamming)) {
    *current = std::move(trial);
  }
}

}  // namespace

std::optional<BlurredQuadReading> ReadBlurredQuad(const cv::Mat& g, const apriltag_family_t* family,
                                                  const QuadCorners& q, int max_hamming, double min_contrast) {
  if (!BlurredReadingSupports(family)) return std::nullopt;
  const int w = family->width_at_border;
  // Samples about 1 px apart, 2-3 per module.
  double perimeter = 0.0;
  for (int i = 0; i < 4; ++i) perimeter += (q[(i + 1) % 4] - q[i]).norm();
  const double module_px = perimeter / (4.0 * w);
  const int k = std::clamp(static_cast<int>(std::lround(module_px)), 2, 3);
  const int m = (w + 2) * k;
  Eigen::VectorXd coords(m);
  for (int a = 0; a < m; ++a) coords[a] = -1.0 + (a + 0.5) / k;

  // Cheap screens first. The module-centre reading within a quarter of the
  // bits: on swatbotics and on synthetic tags of 14-22 px blurred by 1-1.8 px
  // it costs no tag that the fit reads, and skips most of the candidates
  // (~2/3 of the time on photos without tags).
  if (!ReadQuad(g, family, q, static_cast<int>(family->nbits) / 4, min_contrast)) return std::nullopt;
  std::optional<Eigen::MatrixXd> first = SampleTag(g, q, w, coords);
  if (!first) return std::nullopt;
  // Then the model at a middle blur: a quad that reads nothing like a code
  // at its first corners is not worth fitting: a non-tag's nearest code (of
  // ncodes x 8 orders) differs in about a fifth of the bits or more, a real
  // tag's at aruco's corners (measured on swatbotics) in up to 5 of 36.
  const int screen = std::max(max_hamming, static_cast<int>(family->nbits) / 6);
  if (!ReadCode(BlurModel(coords, w, Blur{0.5, 0.5, 0.0}).Solve(*first, nullptr).bits, q, family, screen)) {
    return std::nullopt;
  }

  // Corners and a separable blur in turn, twice (the blur found at aruco's
  // corners is too wide: their error looks like blur).
  TagFit tag;
  tag.corners = q;
  tag.grey = std::move(*first);
  tag.model = SearchBlur(tag.grey, coords, w);
  for (int round = 0; round < 2 && tag.model; ++round) {
    tag.corners = FitCorners(g, tag.corners, w, coords, *tag.model, 2.0 * module_px);
    std::optional<Eigen::MatrixXd> grey = SampleTag(g, tag.corners, w, coords);
    if (!grey) return std::nullopt;
    tag.grey = std::move(*grey);
    tag.model = SearchBlur(tag.grey, coords, w);
  }
  if (!tag.model) return std::nullopt;
  tag.fit = tag.model->Solve(tag.grey, nullptr);
  tag.code = ReadCode(tag.fit.bits, tag.corners, family, max_hamming);
  if (!tag.code || tag.code->reading.hamming > 0) TryTiltedBlur(g, family, coords, module_px, max_hamming, &tag);
  if (!tag.code || !(tag.fit.mean_contrast >= min_contrast)) return std::nullopt;

  // The code's own bits, levels re-fitted: how well the tag explains the image.
  const BlurModel::Fit exact = tag.model->Solve(tag.grey, &tag.code->bits);
  BlurredQuadReading r;
  r.reading = tag.code->reading;
  r.reading.contrast = tag.fit.mean_contrast;
  r.residual = exact.rms / std::max(exact.mean_contrast, 1e-9);
  r.blur_u = tag.model->blur().sigma_u;
  r.blur_v = tag.model->blur().sigma_v;
  r.blur_correlation = tag.model->blur().rho;
  return r;
}

}  // namespace tagsfm::detail
