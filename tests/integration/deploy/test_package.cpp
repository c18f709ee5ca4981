// The Debian package (cmake/OdonavPackaging.cmake): built by cpack from this build, installed with
// apt-get, its units checked by `systemd-analyze verify`, a short pipeline run from the installed
// binaries and profile (deploy/launch on DDS domain 168, loopback profile from /etc/odonav), then
// purged, leaving nothing behind. It installs into the running system, so it needs root (CI runs as
// root) and skips otherwise, or when an odonav package is already installed.
#include <gtest/gtest.h>

#include "child_process.hpp"

#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <string>

namespace fs = std::filesystem;

using odonav::test::CommandResult;
const auto run = odonav::test::run_command;

namespace {

const char* kPrograms[] = {"odonav-gateway",   "odonav-calibration", "odonav-identification", "odonav-dead-reckoning",
                           "odonav-recorder",  "odonav-ground",      "odonav-offline",        "odonav-evaluate",
                           "odonav-simulator", "odonav-report"};

}  // namespace

TEST(DeployPackage, InstallsRunsAndPurgesLeavingNothingBehind) {
  if (::geteuid() != 0) GTEST_SKIP() << "installs a package into the system: needs root";
  if (run("dpkg-query -W -f='${Status}' odonav").output.find("installed") != std::string::npos)
    GTEST_SKIP() << "an odonav package is installed already: not touched";
  const fs::path tmp = fs::temp_directory_path() / ("odonav-test-package-" + std::to_string(::getpid()));
  fs::remove_all(tmp);
  fs::create_directories(tmp);

  // The package of this build.
  const CommandResult pack =
      run("cd " + std::string(ODONAV_BINARY_DIR) + " && cpack -G DEB -B " + (tmp / "pkg").string());
  ASSERT_EQ(pack.status, 0) << pack.output;
  fs::path deb;
  for (const auto& e : fs::directory_iterator(tmp / "pkg"))
    if (e.path().extension() == ".deb") deb = e.path();
  ASSERT_FALSE(deb.empty()) << pack.output;
  const CommandResult fields = run("dpkg-deb -f " + deb.string() + " Package Version Depends");
  EXPECT_NE(fields.output.find("Package: odonav"), std::string::npos) << fields.output;
  EXPECT_NE(fields.output.find("libfastrtps"), std::string::npos)
      << "Depends from the shared libraries: " << fields.output;
  EXPECT_NE(fields.output.find("adduser"), std::string::npos) << fields.output;

  const CommandResult install = run("DEBIAN_FRONTEND=noninteractive apt-get install -y -q " + deb.string());
  ASSERT_EQ(install.status, 0) << install.output;
  for (const char* p : kPrograms) EXPECT_TRUE(fs::exists(fs::path("/usr/bin") / p)) << p;
  EXPECT_TRUE(fs::exists("/etc/odonav/profiles/loopback.xml"));
  EXPECT_TRUE(fs::exists("/etc/odonav/vehicle.env"));
  EXPECT_EQ(run("getent passwd odonav").status, 0) << "the system user the units run as";
  const CommandResult conffiles = run("dpkg-query -W -f='${Conffiles}' odonav");
  EXPECT_NE(conffiles.output.find("/etc/odonav/vehicle.env"), std::string::npos) << conffiles.output;
  EXPECT_NE(conffiles.output.find("/etc/odonav/profiles/vehicle.xml"), std::string::npos) << conffiles.output;
  // Nothing enabled or started.
  EXPECT_NE(run("systemctl is-enabled odonav-identification.service").output.find("enabled\n"), 0u);
  const CommandResult verify =
      run("systemd-analyze verify /usr/lib/systemd/system/odonav-*.service /usr/lib/systemd/system/odonav.target");
  EXPECT_EQ(verify.status, 0) << verify.output;

  // A short pipeline from the installed binaries and profile.
  fs::create_directories(tmp / "installed");
  fs::create_symlink("/usr/bin", tmp / "installed/bin");
  run("fastdds shm clean");
  const CommandResult pipeline =
      run(std::string(ODONAV_SOURCE_DIR) + "/deploy/launch --source sim:terrain --duration-s 60 --speed max --out " +
          (tmp / "out").string() + " --build-dir " + (tmp / "installed").string() +
          " --profile /etc/odonav/profiles/loopback.xml --domain 168");
  run("fastdds shm clean");
  EXPECT_EQ(pipeline.status, 0) << pipeline.output;
  EXPECT_TRUE(fs::exists(tmp / "out/summary.json")) << pipeline.output;
  EXPECT_TRUE(fs::exists(tmp / "out/scale_factor.csv")) << pipeline.output;

  const CommandResult purge = run("DEBIAN_FRONTEND=noninteractive apt-get purge -y -q odonav");
  EXPECT_EQ(purge.status, 0) << purge.output;
  EXPECT_NE(run("dpkg-query -W -f='${Status}' odonav").output.find("install ok installed"), 0u);
  EXPECT_EQ(run("dpkg -L odonav").status != 0, true);
  for (const char* p : kPrograms) EXPECT_FALSE(fs::exists(fs::path("/usr/bin") / p)) << p;
  EXPECT_FALSE(fs::exists("/etc/odonav"));
  EXPECT_FALSE(fs::exists("/var/lib/odonav"));
  EXPECT_FALSE(fs::exists("/usr/lib/systemd/system/odonav.target"));
  EXPECT_NE(run("getent passwd odonav").status, 0) << "the system user is removed on purge";
  fs::remove_all(tmp);
}
