// deploy/install into a temporary root (DESTDIR), the installed units checked by
// `systemd-analyze verify`, and deploy/uninstall removing what install put there.
// The binaries are stand-in scripts in a temporary build dir: what is checked here is the install
// layout and the units, not the programs (their own tests run them). In the staging root,
// usr/lib/systemd/system links to the host's (so the units' dependencies such as
// network-online.target resolve) and usr/bin/fastdds to the host's tool (Debian fastdds-tools),
// because verify --root resolves ExecStart inside the root.
#include <gtest/gtest.h>

#include "child_process.hpp"

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <unistd.h>

namespace fs = std::filesystem;

using odonav::test::CommandResult;
const auto run = odonav::test::run_command;

namespace {

const fs::path kDeploy = fs::path(ODONAV_SOURCE_DIR) / "deploy";
const char* kComponents[] = {"gateway", "calibration", "identification", "dead-reckoning"};

std::string read(const fs::path& file) {
  std::ifstream in(file);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace

class DeployInstall : public ::testing::Test {
 protected:
  void SetUp() override {
    tmp_ = fs::temp_directory_path() / ("odonav-test-install-" + std::to_string(::getpid()));
    fs::remove_all(tmp_);
    root_ = tmp_ / "root";
    fs::create_directories(tmp_ / "build/bin");
    for (const char* c : kComponents) {
      const fs::path bin = tmp_ / "build/bin" / (std::string("odonav-") + c);
      std::ofstream(bin) << "#!/bin/sh\nexit 0\n";
      fs::permissions(bin, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec);
    }
    const CommandResult pki = run(kDeploy.string() + "/security/make-pki --out " + (tmp_ / "pki").string());
    ASSERT_EQ(pki.status, 0) << pki.output;
    const CommandResult install =
        run(kDeploy.string() + "/install --destdir " + root_.string() + " --build-dir " + (tmp_ / "build").string() +
            " --ecu-address 127.0.77.12 --security-dir " + (tmp_ / "pki").string() + " --no-user");
    ASSERT_EQ(install.status, 0) << install.output;
  }
  void TearDown() override { fs::remove_all(tmp_); }
  fs::path tmp_, root_;
};

TEST_F(DeployInstall, PutsEverythingInPlaceWithTheEcuAddress) {
  for (const char* c : kComponents) {
    EXPECT_TRUE(fs::exists(root_ / "usr/local/bin" / (std::string("odonav-") + c))) << c;
    EXPECT_TRUE(fs::exists(root_ / "etc/systemd/system" / (std::string("odonav-") + c + ".service"))) << c;
    EXPECT_TRUE(fs::exists(root_ / "etc/odonav/security" / (std::string("odonav-") + c) / "key.pem")) << c;
  }
  EXPECT_TRUE(fs::exists(root_ / "etc/systemd/system/odonav.target"));
  EXPECT_TRUE(fs::exists(root_ / "etc/odonav/vehicle.env"));
  const std::string vehicle = read(root_ / "etc/odonav/profiles/vehicle.xml");
  EXPECT_NE(vehicle.find("<address>127.0.77.12</address>"), std::string::npos);
  EXPECT_EQ(vehicle.find("ECU_ADDRESS</address>"), std::string::npos);
  // The CA private keys never leave the PKI directory; the component key is private.
  EXPECT_FALSE(fs::exists(root_ / "etc/odonav/security/private"));
  const auto key_perms = fs::status(root_ / "etc/odonav/security/odonav-gateway/key.pem").permissions();
  EXPECT_EQ(key_perms & (fs::perms::group_all | fs::perms::others_all), fs::perms::none);
  // The ground station's identity is not on an ECU.
  EXPECT_FALSE(fs::exists(root_ / "etc/odonav/security/odonav-ground"));
}

TEST_F(DeployInstall, SystemdAnalyzeVerifiesEveryUnit) {
  const CommandResult which = run("command -v systemd-analyze");
  ASSERT_EQ(which.status, 0) << "systemd-analyze not found: install the Debian package 'systemd' "
                                "(scripts/install-deps lists it); the units cannot be verified without it";
  fs::create_directories(root_ / "usr/lib/systemd");
  fs::create_directories(root_ / "usr/bin");
  const fs::path host_units =
      fs::exists("/lib/systemd/system/multi-user.target") ? "/lib/systemd/system" : "/usr/lib/systemd/system";
  ASSERT_TRUE(fs::exists(host_units / "network-online.target"))
      << "the host has no systemd unit directory with network-online.target (" << host_units
      << "): verify needs the standard targets the units depend on";
  fs::create_symlink(host_units, root_ / "usr/lib/systemd/system");
  const CommandResult fastdds = run("command -v fastdds");
  ASSERT_EQ(fastdds.status, 0) << "fastdds (Debian fastdds-tools) not found: the discovery-server unit runs it";
  // A copy: Debian's /usr/bin/fastdds is a relative symlink that would resolve inside the root.
  fs::copy_file(fs::canonical(fastdds.output.substr(0, fastdds.output.find('\n'))), root_ / "usr/bin/fastdds");

  std::string units;
  for (const char* c : kComponents) units += " /etc/systemd/system/odonav-" + std::string(c) + ".service";
  units += " /etc/systemd/system/odonav-discovery-server.service /etc/systemd/system/odonav.target";
  const CommandResult verify = run("systemd-analyze verify --root=" + root_.string() + units);
  EXPECT_EQ(verify.status, 0) << verify.output;
  EXPECT_EQ(verify.output, "") << "verify printed warnings";

  // Control: verify does catch a broken unit (its binary missing).
  fs::remove(root_ / "usr/local/bin/odonav-gateway");
  const CommandResult broken =
      run("systemd-analyze verify --root=" + root_.string() + " /etc/systemd/system/odonav-gateway.service");
  EXPECT_NE(broken.status, 0);
  EXPECT_NE(broken.output.find("odonav-gateway"), std::string::npos) << broken.output;
}

TEST_F(DeployInstall, UnitsCarryTheDeploymentRules) {
  const std::string identification = read(root_ / "etc/systemd/system/odonav-identification.service");
  for (const char* needle : {"EnvironmentFile=/etc/odonav/vehicle.env", "Restart=on-failure", "User=odonav",
                             "StateDirectory=odonav/identification", "ExecStartPre=-/usr/bin/fastdds shm clean",
                             "--profile ${ODONAV_PROFILE}", "--domain ${ODONAV_DOMAIN}", "PartOf=odonav.target"})
    EXPECT_NE(identification.find(needle), std::string::npos) << needle;
  EXPECT_EQ(identification.find("DynamicUser=yes"), std::string::npos);
  // Dead reckoning resumes its track from its checkpoint after a restart.
  const std::string dead_reckoning = read(root_ / "etc/systemd/system/odonav-dead-reckoning.service");
  for (const char* needle : {"StateDirectory=odonav/dead-reckoning", "--state-dir ${ODONAV_STATE_DIR}",
                             "Environment=ODONAV_STATE_DIR=/var/lib/odonav/dead-reckoning"})
    EXPECT_NE(dead_reckoning.find(needle), std::string::npos) << needle;
}

TEST_F(DeployInstall, UninstallRemovesWhatInstallPut) {
  std::ofstream(root_ / "etc/odonav/vehicle.env", std::ios::app) << "# edited by the admin\n";
  const CommandResult keep = run(kDeploy.string() + "/uninstall --destdir " + root_.string());
  ASSERT_EQ(keep.status, 0) << keep.output;
  EXPECT_FALSE(fs::exists(root_ / "usr/local/bin/odonav-gateway"));
  EXPECT_FALSE(fs::exists(root_ / "etc/systemd/system/odonav.target"));
  EXPECT_FALSE(fs::exists(root_ / "etc/odonav/security"));
  EXPECT_NE(read(root_ / "etc/odonav/vehicle.env").find("edited by the admin"), std::string::npos);

  // A second install keeps the admin's environment file; --purge removes it too.
  ASSERT_EQ(run(kDeploy.string() + "/install --destdir " + root_.string() + " --build-dir " +
                (tmp_ / "build").string() + " --no-user")
                .status,
            0);
  EXPECT_NE(read(root_ / "etc/odonav/vehicle.env").find("edited by the admin"), std::string::npos);
  const CommandResult purge = run(kDeploy.string() + "/uninstall --destdir " + root_.string() + " --purge");
  ASSERT_EQ(purge.status, 0) << purge.output;
  EXPECT_FALSE(fs::exists(root_ / "etc/odonav"));
  EXPECT_FALSE(fs::exists(root_ / "usr/local/bin"));
}
