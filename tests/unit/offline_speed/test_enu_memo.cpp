// LocalEnuFrame::to_enu keeps a small per-thread memo of its last answers (geodesy.cpp). These tests
// hold it to "returns exactly what the computation returns": every answer is compared bit for bit
// with a frame built just for that query (a new frame never hits the memo), over access patterns
// that hit, miss and evict, with several frames alive at once, and from two threads at a time.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <thread>
#include <vector>

#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

namespace odonav {
namespace {

bool same_bits(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::memcmp(a.data(), b.data(), sizeof(double) * 3) == 0;
}

// The answer without any memo: a fresh frame has a new identity, so its first call computes.
Eigen::Vector3d fresh_to_enu(const Geodetic& origin, const Geodetic& p) { return LocalEnuFrame(origin).to_enu(p); }

std::vector<Geodetic> positions_near(const Geodetic& origin, std::size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> d_rad(-1e-3, 1e-3), d_h(-50.0, 50.0);
  std::vector<Geodetic> out;
  for (std::size_t i = 0; i < n; ++i)
    out.push_back({origin.lat_rad + d_rad(rng), origin.lon_rad + d_rad(rng), origin.height_m + d_h(rng)});
  return out;
}

TEST(EnuMemo, RepeatedAndInterleavedQueriesAreBitIdenticalToAFreshComputation) {
  const Geodetic origin{52.5 * kDegToRad, 13.4 * kDegToRad, 80.0};
  const LocalEnuFrame frame(origin);
  const std::vector<Geodetic> fixes = positions_near(origin, 8, 1);
  const std::vector<Geodetic> track = positions_near(origin, 200, 2);
  std::vector<Eigen::Vector3d> expected_fix, expected_track;
  for (const Geodetic& g : fixes) expected_fix.push_back(fresh_to_enu(origin, g));
  for (const Geodetic& g : track) expected_track.push_back(fresh_to_enu(origin, g));
  // The dead reckoner's pattern: a new position, then the two bracketing fixes, again and again;
  // the fixes advance every 10 steps, so entries are evicted too.
  for (std::size_t i = 0; i < track.size(); ++i) {
    const std::size_t lo = (i / 10) % (fixes.size() - 1);
    EXPECT_TRUE(same_bits(frame.to_enu(track[i]), expected_track[i])) << "track " << i;
    EXPECT_TRUE(same_bits(frame.to_enu(fixes[lo]), expected_fix[lo])) << "fix " << lo;
    EXPECT_TRUE(same_bits(frame.to_enu(fixes[lo + 1]), expected_fix[lo + 1])) << "fix " << lo + 1;
  }
}

TEST(EnuMemo, TwoFramesNeverShareAnAnswer) {
  // Same query position, two frames with different origins: each must get its own answer even
  // when the calls alternate (the memo is keyed by the frame too).
  const Geodetic a_origin{52.5 * kDegToRad, 13.4 * kDegToRad, 80.0};
  const Geodetic b_origin{52.501 * kDegToRad, 13.401 * kDegToRad, 90.0};
  const LocalEnuFrame a(a_origin), b(b_origin);
  const Geodetic p{52.5005 * kDegToRad, 13.4005 * kDegToRad, 85.0};
  const Eigen::Vector3d expected_a = fresh_to_enu(a_origin, p), expected_b = fresh_to_enu(b_origin, p);
  ASSERT_GT((expected_a - expected_b).norm(), 50.0);  // the two answers really differ
  for (int i = 0; i < 5; ++i) {
    EXPECT_TRUE(same_bits(a.to_enu(p), expected_a));
    EXPECT_TRUE(same_bits(b.to_enu(p), expected_b));
  }
  // A frame assigned a new origin answers for the new origin at once.
  LocalEnuFrame c(a_origin);
  EXPECT_TRUE(same_bits(c.to_enu(p), expected_a));
  c = b;
  EXPECT_TRUE(same_bits(c.to_enu(p), expected_b));
}

TEST(EnuMemo, SignedZeroIsNotConfusedWithZero) {
  // -0.0 == 0.0 as numbers, but the memo compares bit patterns: the answer for each is the one the
  // computation gives for that exact input.
  const Geodetic origin{0.0, 0.0, 0.0};
  const LocalEnuFrame frame(origin);
  const Geodetic plus{0.0, 0.0, 10.0}, minus{-0.0, -0.0, 10.0};
  const Eigen::Vector3d e_plus = fresh_to_enu(origin, plus), e_minus = fresh_to_enu(origin, minus);
  EXPECT_TRUE(same_bits(frame.to_enu(plus), e_plus));
  EXPECT_TRUE(same_bits(frame.to_enu(minus), e_minus));
  EXPECT_TRUE(same_bits(frame.to_enu(plus), e_plus));
}

TEST(EnuMemo, ConcurrentCallsOnOneFrameGiveTheComputedAnswers) {
  const Geodetic origin{48.1 * kDegToRad, 11.6 * kDegToRad, 520.0};
  const LocalEnuFrame frame(origin);
  const std::vector<Geodetic> points = positions_near(origin, 300, 3);
  std::vector<Eigen::Vector3d> expected;
  for (const Geodetic& g : points) expected.push_back(fresh_to_enu(origin, g));
  auto worker = [&](std::size_t offset, int* mismatches) {
    for (int round = 0; round < 20; ++round)
      for (std::size_t i = 0; i < points.size(); ++i) {
        const std::size_t k = (i * 7 + offset + static_cast<std::size_t>(round)) % points.size();
        if (!same_bits(frame.to_enu(points[k]), expected[k])) ++*mismatches;
      }
  };
  int m1 = 0, m2 = 0;
  std::thread t1(worker, 0, &m1), t2(worker, 5, &m2);
  t1.join();
  t2.join();
  EXPECT_EQ(m1, 0);
  EXPECT_EQ(m2, 0);
}

}  // namespace
}  // namespace odonav
