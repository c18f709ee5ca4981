// admit_sample: what a node does with each input sample before its core sees it (event-time
// aligner verdicts, counters, reasons), without a participant.
#include <gtest/gtest.h>

#include <vector>

#include "odonav/dds/node_support.hpp"
#include "odonav/dds/time.hpp"

namespace {

using namespace odonav;
using namespace odonav::dds;

double counter(const HealthCounters& c, const std::string& name) {
  for (const auto& [n, v] : c)
    if (n == name) return v;
  ADD_FAILURE() << "no counter " << name;
  return -1.0;
}

// A producer restarted from its checkpoint (t=50 s) republishes the epochs it had published before
// it was killed (up to 52.5 s), with the same values, before it goes on: on an estimate input those
// are repeats of estimates already applied, not a fault; on a sensor input the same stamps are.
TEST(AdmitSample, EstimatesOlderThanTheLastTakenAreRepublishedRepeatsNotProblems) {
  EventTimeAligner aligner(/*max_wait_s=*/2.0, /*start_s=*/0.0);
  NodeInput estimate;
  estimate.name = "misalignment";
  estimate.id = aligner.add_stream("misalignment");
  estimate.estimate = true;
  NodeInput sensor;
  sensor.name = "odometer";
  sensor.id = aligner.add_stream("odometer");
  std::vector<double> fed;
  auto feed = [&](double t_s) { fed.push_back(t_s); };
  const std::vector<double> stamps = {52.3, 52.4, 52.5, 50.1, 50.2, 52.5, 52.6};
  for (double t : stamps) admit_sample(aligner, estimate, to_time_msg(t), 1.0, feed);
  EXPECT_EQ(fed, (std::vector<double>{52.3, 52.4, 52.5, 52.6}));
  EXPECT_EQ(estimate.republished, 2u);  // 50.1 and 50.2; the second 52.5 is a heartbeat
  EXPECT_EQ(estimate.problems, 0u);
  HealthCounters c;
  append_input_counters(c, aligner, estimate, 1.0);
  EXPECT_EQ(counter(c, "misalignment_rejected"), 0.0);
  EXPECT_EQ(counter(c, "misalignment_republished"), 2.0);
  EXPECT_FALSE(rejection_reason({&estimate}, 1.0).has_value());

  fed.clear();
  for (double t : {10.0, 10.01, 9.99}) admit_sample(aligner, sensor, to_time_msg(t), 1.0, feed);
  EXPECT_EQ(fed, (std::vector<double>{10.0, 10.01}));
  EXPECT_EQ(sensor.republished, 0u);
  EXPECT_EQ(sensor.problems, 1u);
  HealthCounters s;
  append_input_counters(s, aligner, sensor, 1.0);
  EXPECT_EQ(counter(s, "odometer_rejected"), 1.0);
  const auto reason = rejection_reason({&sensor}, 1.0);
  ASSERT_TRUE(reason.has_value());
  EXPECT_NE(reason->find("time went backwards (t=9.99"), std::string::npos) << *reason;
}

}  // namespace
