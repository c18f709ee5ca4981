// odonav-dead-reckoning: SINS/odometer dead reckoning as a DDS process (README.md).
#include "node/dead_reckoning_node.hpp"

int main(int argc, char** argv) {
  return odonav::dds::run_component(
      argc, argv, "odonav-dead-reckoning",
      "Dead-reckons with the SINS attitude and the odometer (docs/ALGORITHM.md section 4): reads rt/odonav/odometer, "
      "rt/odonav/ins/attitude, rt/odonav/gnss/fix, rt/odonav/misalignment and rt/odonav/scale_factor, publishes "
      "rt/odonav/dead_reckoning and the GNSS-anchored rt/odonav/navigation_position once per odometer sample, in "
      "event time. Uses the nominal K until an identified "
      "K converges, and goes on without identification. Stops on SIGINT/SIGTERM after publishing every output.",
      [](odonav::Options& o) { odonav::dead_reckoning::add_dead_reckoning_node_options(o); },
      [](const odonav::Options& o, odonav::dds::ComponentRuntime& runtime) {
        odonav::dead_reckoning::DeadReckoningNode node(
            runtime, odonav::dead_reckoning::dead_reckoning_node_params_from(o),
            odonav::dead_reckoning::anchored_position_node_params_from(o), odonav::checkpoint_settings_from_options(o));
        return node.run();
      });
}
