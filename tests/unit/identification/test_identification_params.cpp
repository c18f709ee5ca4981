// identification_params_for: the one function odonav-identification and odonav-offline build their
// IdentificationParams with, so the same options and vehicle facts give the same parameters.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

#include "odonav/config.hpp"
#include "odonav/identification/identification_options.hpp"

namespace {

using namespace odonav;
using namespace odonav::identification;

Options parsed(const std::vector<std::string>& args) {
  Options o("test", "identification options");
  add_identification_options(o);
  std::ostringstream help;
  o.parse(args, help);
  return o;
}

TEST(IdentificationParamsFor, TakesTheVehicleFactsOnTopOfTheOptions) {
  const Options o = parsed({"--window", "250", "--id-min-speed", "2.5"});
  IdentificationVehicleFacts facts;
  facts.use_ins = false;
  facts.lever_arm_body_m = Eigen::Vector3d(0.5, -0.25, 2.0);
  facts.nominal_k_m_per_pulse = 0.02;
  facts.run_all_estimators = true;
  const IdentificationParams p = identification_params_for(o, facts);
  EXPECT_EQ(p.estimator.window_length, 250u) << "the options are read as identification_params_from reads them";
  EXPECT_EQ(p.builder.min_speed_mps, 2.5);
  EXPECT_FALSE(p.builder.use_ins);
  ASSERT_TRUE(p.builder.lever_arm_body_m);
  EXPECT_EQ(*p.builder.lever_arm_body_m, Eigen::Vector3d(0.5, -0.25, 2.0));
  EXPECT_TRUE(p.run_all_estimators);
  // The pulse-jump gate uses the vehicle's nominal K: 100 m/s at 0.02 m/pulse = 5000 pulses/s,
  // plus the 2-pulse margin, over a 10 ms odometer interval.
  EXPECT_EQ(p.builder.odometer_jump_gate.k_m_per_pulse, 0.02);
  EXPECT_DOUBLE_EQ(p.builder.odometer_jump_gate.max_increment_pulses(0.01), 52.0);
}

TEST(IdentificationParamsFor, DefaultFactsAreTheSimulatedTrackedVehicle) {
  const IdentificationParams p = identification_params_for(parsed({}), {});
  EXPECT_TRUE(p.builder.use_ins);
  EXPECT_FALSE(p.builder.lever_arm_body_m);
  EXPECT_FALSE(p.run_all_estimators);
  EXPECT_EQ(p.builder.odometer_jump_gate.k_m_per_pulse, 0.0125);
  EXPECT_DOUBLE_EQ(p.builder.odometer_jump_gate.max_increment_pulses(0.01), 82.0);
  EXPECT_EQ(p.estimator_name, "vff_lm_rls");
}

TEST(IdentificationParamsFor, RefusesANominalKThatIsNotPositiveAndFinite) {
  const Options o = parsed({});
  for (double bad : {0.0, -0.0125, std::nan(""), HUGE_VAL}) {
    IdentificationVehicleFacts facts;
    facts.nominal_k_m_per_pulse = bad;
    try {
      identification_params_for(o, facts);
      ADD_FAILURE() << "accepted nominal K " << bad;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("nominal K must be finite and > 0 m/pulse"), std::string::npos) << e.what();
    }
  }
}

}  // namespace

namespace {

std::string identification_error(const std::vector<std::string>& args) {
  try {
    (void)odonav::identification::identification_params_from(parsed(args));
  } catch (const odonav::ConfigError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(IdentificationOptions, FormerGateNamesAreRefusedNamingTheNewOnes) {
  EXPECT_EQ(identification_error({"--min-speed=2.5"}), "--min-speed was renamed --id-min-speed");
  EXPECT_EQ(identification_error({"--max-yaw-rate-deg-s", "4"}),
            "--max-yaw-rate-deg-s was renamed --id-max-yaw-rate-deg-s");
  EXPECT_EQ(identification_error({"--no-braking-stop"}), "--no-braking-stop was renamed --no-id-braking-stop");
  EXPECT_EQ(identification_error({"--braking-stop-decel-mps2=1"}),
            "--braking-stop-decel-mps2 was renamed --id-braking-stop-decel-mps2");
  EXPECT_EQ(identification_error({"--id-min-speed=2.5", "--no-id-braking-stop", "--id-max-yaw-rate-deg-s=4"}), "");
}
