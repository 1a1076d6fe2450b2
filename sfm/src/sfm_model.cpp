#include "tagsfm/sfm/sfm_model.h"

namespace tagsfm::sfm {

int SfmModel::RegisteredImages() const {
  int n = 0;
  for (const SfmImage& image : images) n += image.registered ? 1 : 0;
  return n;
}

int SfmModel::LivePoints() const {
  int n = 0;
  for (const SfmPoint& p : points) n += p.deleted ? 0 : 1;
  return n;
}

PointIdx SfmModel::AddPoint(const Eigen::Vector3d& xyz, const std::array<std::uint8_t, 3>& rgb,
                            std::vector<Observation> track) {
  const PointIdx id = static_cast<PointIdx>(points.size());
  for (const Observation& obs : track) images[obs.image].point_of_feature[obs.feature] = id;
  points.push_back({xyz, rgb, std::move(track), false});
  return id;
}

void SfmModel::AddObservation(PointIdx point, Observation obs) {
  images[obs.image].point_of_feature[obs.feature] = point;
  points[point].track.push_back(obs);
}

void SfmModel::DeletePoint(PointIdx point) {
  for (const Observation& obs : points[point].track) images[obs.image].point_of_feature[obs.feature] = -1;
  points[point].track.clear();
  points[point].deleted = true;
}

void SfmModel::RemoveObservation(PointIdx point, size_t track_index) {
  std::vector<Observation>& track = points[point].track;
  const Observation obs = track[track_index];
  images[obs.image].point_of_feature[obs.feature] = -1;
  track.erase(track.begin() + static_cast<std::ptrdiff_t>(track_index));
}

}  // namespace tagsfm::sfm
