// odonav-recorder: writes what the pipeline publishes as odonav-offline's CSV files (README.md).
#include "node/recorder_node.hpp"

int main(int argc, char** argv) {
  return odonav::dds::run_component(
      argc, argv, "odonav-recorder",
      "Subscribes to rt/odonav/misalignment, rt/odonav/scale_factor and rt/odonav/dead_reckoning (and "
      "rt/odonav/health, for the log) of one vehicle and writes misalignment.csv, scale_factor.csv and "
      "dead_reckoning.csv into --out, the same files and columns as odonav-offline. Logs progress every "
      "--progress-every-s of simulated time. On SIGINT/SIGTERM writes everything received, closes the files, exits 0.",
      [](odonav::Options& o) { odonav::recorder::add_recorder_options(o); },
      [](const odonav::Options& o, odonav::dds::ComponentRuntime& runtime) {
        odonav::recorder::RecorderNode node(runtime, odonav::recorder::recorder_settings_from(o));
        return node.run();
      });
}
