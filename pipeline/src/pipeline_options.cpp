#include "tagsfm/pipeline/pipeline_options.h"

#include <string_view>

namespace tagsfm {
namespace {

// A stage's Check() names its fields by its own prefix ("pose.", "ba.", or
// none); the message names them by their place in the `pipeline:` block.
Status Placed(Status status, std::string_view own_prefix, const std::string& place) {
  if (status) return status;
  std::string message = status.error().message;
  if (!own_prefix.empty() && message.rfind(own_prefix, 0) == 0) message.erase(0, own_prefix.size());
  return MakeError(place + message);
}

}  // namespace

Status PipelineOptions::Check() const {
  if (Status s = Placed(detector.Check(), "", "pipeline.detector."); !s) return s;
  if (Status s = Placed(tracker.Check(), "", "pipeline.tracker."); !s) return s;
  if (Status s = Placed(recon.pose.Check(), "pose.", "pipeline.recon.pose."); !s) return s;
  if (Status s = Placed(recon.ba.Check(), "ba.", "pipeline.recon.ba."); !s) return s;
  if (Status s = Placed(recon.Check(), "recon.", "pipeline.recon."); !s) return s;
  if (Status s = Placed(features.Check(), "features.", "pipeline.features."); !s) return s;
  if (Status s = Placed(feedback.Check(), "feedback.", "pipeline.feedback."); !s) return s;
  return Status::Ok();
}

}  // namespace tagsfm
