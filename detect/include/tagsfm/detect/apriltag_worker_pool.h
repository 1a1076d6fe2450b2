#pragma once
// A safe start for libapriltag 3.3's worker threads.
//
// libapriltag 3.3 (Debian 12) starts a detector's worker pool inside the
// first apriltag_detector_detect with nthreads > 1, and its first run races
// with the threads' start: workerpool_run resets its count of finished
// threads without the lock while a starting thread counts itself, so the
// run can return while a thread is still working on a task whose data the
// detector then frees (fixed upstream after 3.3: AprilRobotics/apriltag
// PR #339, issue #70). Measured here: creating a detector, detecting once
// with 2 threads and destroying it crashed within 100-500 cycles, every time.
// A first run with no tasks at all cannot cut work short, and leaves the
// threads waiting for the next one.
struct apriltag_detector;

namespace tagsfm {

// Starts the pool of `detector` (its nthreads and families already set) by
// detecting on a 3 x 3 image, which gives libapriltag's stages no task.
// Call once after setting up the detector, before its first real detection.
void StartAprilTagWorkerPool(apriltag_detector* detector);

}  // namespace tagsfm
