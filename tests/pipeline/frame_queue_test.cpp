// The queue between capture and the pipeline: capture never waits; when the
// pipeline falls behind, the oldest waiting frames are dropped and counted.
#include <thread>

#include <gtest/gtest.h>

#include "tagsfm/pipeline/frame_queue.h"

namespace tagsfm {
namespace {

Frame FrameNumber(FrameId i) {
  Frame f;
  f.index = i;
  return f;
}

TEST(FrameQueue, DropsTheOldestWaitingFramesBeyondItsCapacity) {
  FrameQueue queue(2);
  for (FrameId i = 0; i < 5; ++i) queue.Push(FrameNumber(i));
  queue.Close();
  EXPECT_EQ(queue.dropped(), 3u);
  auto a = queue.Pop();
  auto b = queue.Pop();
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->index, 3);
  EXPECT_EQ(b->index, 4);
  EXPECT_FALSE(queue.Pop());
}

TEST(FrameQueue, AConsumerGetsEveryFrameInOrderWhenItKeepsUp) {
  FrameQueue queue(1000);
  std::thread producer([&] {
    for (FrameId i = 0; i < 500; ++i) queue.Push(FrameNumber(i));
    queue.Close();
  });
  FrameId expected = 0;
  while (auto frame = queue.Pop()) EXPECT_EQ(frame->index, expected++);
  producer.join();
  EXPECT_EQ(expected, 500);
  EXPECT_EQ(queue.dropped(), 0u);
}

}  // namespace
}  // namespace tagsfm
