#include "tagsfm/detect/tag_layout.h"

#include <memory>

#include <Eigen/LU>

#include "apriltag_family.h"

namespace tagsfm {

namespace detail {

TagLayout LayoutOf(apriltag_family_t* fam, TagId id) {
  std::unique_ptr<image_u8_t, void (*)(image_u8_t*)> bitmap(apriltag_to_image(fam, id), image_u8_destroy);
  TagLayout layout;
  const int n = fam->width_at_border;
  const int start = (fam->total_width - n) / 2;
  layout.modules_across = n;
  layout.like_border.resize(static_cast<size_t>(n * n));
  const uint8_t border = bitmap->buf[start * bitmap->stride + start];
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      layout.like_border[static_cast<size_t>(row * n + col)] =
          bitmap->buf[(row + start) * bitmap->stride + col + start] == border;
    }
  }
  return layout;
}

}  // namespace detail

Result<TagLayout> MakeTagLayout(const std::string& family_name, TagId id) {
  Result<detail::FamilyPtr> family = detail::CreateAprilTagFamily(family_name);
  if (!family) return family.error();
  if (id < 0 || id >= static_cast<int>((*family)->ncodes)) {
    return MakeError("tag id " + std::to_string(id) + " is not in " + family_name);
  }
  return detail::LayoutOf(family->get(), id);
}

QuadCorners CornerSquareCorners(int n) {
  return {Eigen::Vector2d(0, n), Eigen::Vector2d(n, n), Eigen::Vector2d(n, 0), Eigen::Vector2d(0, 0)};
}

std::optional<Eigen::Matrix3d> HomographyFrom4(const QuadCorners& from, const QuadCorners& to) {
  Eigen::Matrix<double, 8, 8> a;
  Eigen::Matrix<double, 8, 1> b;
  for (int k = 0; k < 4; ++k) {
    const double x = from[k].x(), y = from[k].y(), u = to[k].x(), v = to[k].y();
    a.row(2 * k) << x, y, 1, 0, 0, 0, -u * x, -u * y;
    a.row(2 * k + 1) << 0, 0, 0, x, y, 1, -v * x, -v * y;
    b(2 * k) = u;
    b(2 * k + 1) = v;
  }
  Eigen::FullPivLU<Eigen::Matrix<double, 8, 8>> lu(a);
  if (!lu.isInvertible()) return std::nullopt;
  const Eigen::Matrix<double, 8, 1> h = lu.solve(b);
  Eigen::Matrix3d m;
  m << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), 1.0;
  return m;
}

}  // namespace tagsfm
