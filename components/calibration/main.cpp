// odonav-calibration: the misalignment calibration as a DDS process (README.md).
#include "node/calibration_node.hpp"

int main(int argc, char** argv) {
  return odonav::dds::run_component(
      argc, argv, "odonav-calibration",
      "Calibrates the odometer-to-INS misalignment from GNSS velocity and INS attitude (docs/ALGORITHM.md section 1): "
      "reads rt/odonav/gnss/fix and rt/odonav/ins/attitude, publishes rt/odonav/misalignment once per GNSS "
      "epoch, in event time. With --state-dir it resumes from its checkpoint after a restart. Stops on SIGINT/SIGTERM after publishing every remaining output.",
      [](odonav::Options& o) { odonav::calibration::add_calibration_node_options(o); },
      [](const odonav::Options& o, odonav::dds::ComponentRuntime& runtime) {
        odonav::calibration::CalibrationNode node(runtime, odonav::calibration::calibration_node_params_from(o),
                                                  odonav::checkpoint_settings_from_options(o));
        return node.run();
      });
}
