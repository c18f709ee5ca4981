// odonav-identification: online odometer scale-factor identification as a DDS process (README.md).
#include "node/identification_node.hpp"

int main(int argc, char** argv) {
  return odonav::dds::run_component(
      argc, argv, "odonav-identification",
      "Identifies the odometer scale factor K online (docs/ALGORITHM.md sections 2-3): reads rt/odonav/odometer, "
      "rt/odonav/gnss/fix, rt/odonav/ins/attitude and rt/odonav/misalignment, publishes rt/odonav/scale_factor "
      "once per GNSS epoch, in event time. With --state-dir it resumes from its checkpoint after a restart. Stops on SIGINT/SIGTERM after publishing every remaining output.",
      [](odonav::Options& o) { odonav::identification::add_identification_node_options(o); },
      [](const odonav::Options& o, odonav::dds::ComponentRuntime& runtime) {
        odonav::identification::IdentificationNode node(
            runtime, odonav::identification::identification_node_params_from(o),
            odonav::identification::checkpoint_settings_from(o), odonav::identification::instance_settings_from(o));
        return node.run();
      });
}
