// DDS Security over loopback (deploy/profiles/loopback.xml + the layer's security properties),
// domains 70-75, with two test PKIs made by deploy/security/make-pki at suite start:
// - pki_a: the vehicle's (identity CA A, permissions CA A), every identity of deploy/security/grants;
// - pki_b: an independent one (another CA): a "rogue" with valid-looking material of its own.
// What is checked: valid material exchanges data; a foreign-CA participant and a participant
// without security receive nothing and their fake scale factor never reaches a legitimate reader;
// a writer or reader the permissions do not grant is refused with the layer's clear error; missing
// or mixed material gives an error naming the file or the likely reason; without security
// material a participant is exactly what it was (no dds.sec.* property).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

#include "error_of.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/dds/security.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/topics.hpp"

using namespace std::chrono_literals;
using odonav::dds::Participant;
using odonav::dds::ParticipantOptions;
using odonav::dds::Reader;
using odonav::dds::Writer;
namespace fs = std::filesystem;
namespace topics = odonav::topics;
namespace msg = odonav::msg;
using odonav::test::error_of;

namespace {

constexpr auto kMatchTimeout = 15s;  // secure handshakes take a few round trips; 2 shared cores

const fs::path kSource = ODONAV_SOURCE_DIR;

ParticipantOptions secure_options(int domain, const std::string& identity, const fs::path& security_dir) {
  ParticipantOptions o;
  o.profiles_file = (kSource / "deploy/profiles/loopback.xml").string();
  o.participant_profile = topics::kLoopbackParticipantProfile;
  o.domain_id = domain;
  o.participant_name = identity;
  o.security_dir = security_dir.string();
  return o;
}

msg::ScaleFactor scale_factor(double k_m_per_pulse, double t_s) {
  msg::ScaleFactor m;
  m.header(odonav::dds::make_header(t_s, "odometer"));
  m.vehicle_id("vehicle-01");
  m.k_m_per_pulse(k_m_per_pulse);
  m.sigma_m_per_pulse(1e-5);
  m.estimator("vff-lm-rls");
  m.converged(true);
  return m;
}

/// Collects every k_m_per_pulse a reader receives (listener thread -> test thread).
struct KCollector {
  std::mutex mutex;
  std::vector<double> k;
  void add(const msg::ScaleFactor& m) {
    std::lock_guard<std::mutex> lock(mutex);
    k.push_back(m.k_m_per_pulse());
  }
  std::vector<double> values() {
    std::lock_guard<std::mutex> lock(mutex);
    return k;
  }
};

}  // namespace

class DdsSecurity : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("odonav-test-security-" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_);
    const std::string make_pki = (kSource / "deploy/security/make-pki").string();
    for (const char* name : {"pki_a", "pki_b"}) {
      const std::string cmd = make_pki + " --out " + (root_ / name).string() + " --org odonav-test >" +
                              (root_ / (std::string(name) + ".log")).string() + " 2>&1";
      ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    }
    (void)std::system("fastdds shm clean >/dev/null 2>&1");
  }
  static void TearDownTestSuite() {
    fs::remove_all(root_);
    (void)std::system("fastdds shm clean >/dev/null 2>&1");
  }
  static fs::path pki_a() { return root_ / "pki_a"; }
  static fs::path pki_b() { return root_ / "pki_b"; }
  static inline fs::path root_;
};

TEST_F(DdsSecurity, MakePkiWritesRfc2253SubjectsAndVerifiableSignatures) {
  // The permissions subject must be the certificate subject in RFC 2253 order (docs/DDS.md §6).
  const fs::path dir = pki_a() / "odonav-identification";
  std::ifstream permissions(dir / "permissions.xml");
  const std::string text((std::istreambuf_iterator<char>(permissions)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("<subject_name>CN=odonav-identification,O=odonav-test,C=DE</subject_name>"), std::string::npos)
      << text;
  // Its own topics only: publishes scale_factor and health, never another estimate or a sensor.
  EXPECT_NE(text.find("<topic>rt/odonav/scale_factor</topic>"), std::string::npos);
  EXPECT_EQ(text.find("<topic>rt/odonav/dead_reckoning</topic>"), std::string::npos);
  // Signatures verify against the own permissions CA and not against the other PKI's.
  const auto verify = [](const fs::path& signed_file, const fs::path& ca) {
    const std::string cmd = "openssl smime -verify -in " + signed_file.string() + " -CAfile " + ca.string() +
                            " -out /dev/null >/dev/null 2>&1";
    return std::system(cmd.c_str()) == 0;
  };
  EXPECT_TRUE(verify(pki_a() / "governance.p7s", pki_a() / "permissions_ca.cert.pem"));
  EXPECT_TRUE(verify(dir / "permissions.p7s", pki_a() / "permissions_ca.cert.pem"));
  EXPECT_FALSE(verify(dir / "permissions.p7s", pki_b() / "permissions_ca.cert.pem"));
  const std::string chain = "openssl verify -CAfile " + (pki_a() / "identity_ca.cert.pem").string() + " " +
                            (dir / "cert.pem").string() + " >/dev/null 2>&1";
  EXPECT_EQ(std::system(chain.c_str()), 0);
  const std::string foreign = "openssl verify -CAfile " + (pki_b() / "identity_ca.cert.pem").string() + " " +
                              (dir / "cert.pem").string() + " >/dev/null 2>&1";
  EXPECT_NE(std::system(foreign.c_str()), 0);
}

TEST_F(DdsSecurity, MaterialResolvesFromOptionsThenEnvironmentThenParticipantName) {
  ::unsetenv(odonav::dds::kSecurityDirEnv);
  ::unsetenv(odonav::dds::kSecurityIdentityEnv);
  EXPECT_FALSE(odonav::dds::resolve_security_material("", "", "odonav-gateway").has_value());

  auto m = odonav::dds::resolve_security_material("/etc/odonav/security", "", "odonav-gateway");
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->certificate_file, "/etc/odonav/security/odonav-gateway/cert.pem");
  EXPECT_EQ(m->governance_file, "/etc/odonav/security/governance.p7s");

  ::setenv(odonav::dds::kSecurityDirEnv, "/srv/pki/", 1);
  ::setenv(odonav::dds::kSecurityIdentityEnv, "odonav-ground", 1);
  m = odonav::dds::resolve_security_material("", "", "odonav-gateway");
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->private_key_file, "/srv/pki/odonav-ground/key.pem");
  // Explicit values win over the environment.
  m = odonav::dds::resolve_security_material("/opt/x", "odonav-calibration", "odonav-gateway");
  EXPECT_EQ(m->permissions_file, "/opt/x/odonav-calibration/permissions.p7s");
  ::unsetenv(odonav::dds::kSecurityDirEnv);
  ::unsetenv(odonav::dds::kSecurityIdentityEnv);

  EXPECT_THROW(odonav::dds::resolve_security_material("/etc/odonav/security", "../etc", "x"), std::invalid_argument);
  EXPECT_THROW(odonav::dds::resolve_security_material("/etc/odonav/security", "", ""), std::invalid_argument);

  const auto props = odonav::dds::security_properties(odonav::dds::security_material_paths("/s", "id"));
  ASSERT_EQ(props.size(), 9u);
  EXPECT_EQ(props[0].first, "dds.sec.auth.plugin");
  EXPECT_EQ(props[0].second, "builtin.PKI-DH");
  EXPECT_EQ(props[2].second, "file:///s/id/cert.pem");
  EXPECT_EQ(props[8].second, "builtin.AES-GCM-GMAC");
}

TEST_F(DdsSecurity, WithoutMaterialTheParticipantIsUnchanged) {
  ::unsetenv(odonav::dds::kSecurityDirEnv);
  Participant plain(secure_options(70, "odonav-gateway", ""));
  EXPECT_FALSE(plain.security().has_value());
  for (const auto& p : plain.native().get_qos().properties().properties())
    EXPECT_NE(p.name().rfind("dds.sec.", 0), 0u) << p.name();
}

TEST_F(DdsSecurity, EnvironmentSelectsTheMaterialOfTheParticipantName) {
  ::setenv(odonav::dds::kSecurityDirEnv, pki_a().c_str(), 1);
  ::unsetenv(odonav::dds::kSecurityIdentityEnv);
  Participant secure(secure_options(70, "odonav-calibration", ""));
  ::unsetenv(odonav::dds::kSecurityDirEnv);
  ASSERT_TRUE(secure.security().has_value());
  EXPECT_EQ(secure.security()->identity, "odonav-calibration");
  bool has_auth = false;
  for (const auto& p : secure.native().get_qos().properties().properties())
    if (p.name() == "dds.sec.auth.builtin.PKI-DH.identity_certificate") {
      has_auth = true;
      EXPECT_EQ(p.value(), "file://" + (pki_a() / "odonav-calibration/cert.pem").string());
    }
  EXPECT_TRUE(has_auth);
}

TEST_F(DdsSecurity, ValidMaterialExchangesScaleFactors) {
  Participant identification(secure_options(71, "odonav-identification", pki_a()));
  Participant dead_reckoning(secure_options(71, "odonav-dead-reckoning", pki_a()));
  KCollector received;
  Writer<msg::ScaleFactor> writer(identification, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile);
  Reader<msg::ScaleFactor> reader(dead_reckoning, topics::kScaleFactor.name, topics::kScaleFactor.reader_profile,
                                  [&](const msg::ScaleFactor& m) { received.add(m); });
  ASSERT_TRUE(writer.wait_for_matched(1, kMatchTimeout)) << "secure writer and reader never matched";
  const std::vector<double> sent{0.0512, 0.0513, 0.0514, 0.0515, 0.0516};
  for (std::size_t i = 0; i < sent.size(); ++i) {
    ASSERT_TRUE(writer.write(scale_factor(sent[i], 100.0 + i)));
    // KEEP_LAST 1: let each sample arrive before the next replaces it (bounded wait).
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    while (received.values().size() < i + 1 && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(10ms);
  }
  EXPECT_EQ(received.values(), sent);
}

TEST_F(DdsSecurity, ForeignCaParticipantReceivesNothingAndCannotInject) {
  constexpr int kDomain = 72;
  Participant identification(secure_options(kDomain, "odonav-identification", pki_a()));
  Participant dead_reckoning(secure_options(kDomain, "odonav-dead-reckoning", pki_a()));
  // Valid material of another PKI, same identity names: authentication with pki_a's CA fails.
  Participant rogue_writer_side(secure_options(kDomain, "odonav-identification", pki_b()));
  Participant rogue_reader_side(secure_options(kDomain, "odonav-ground", pki_b()));

  KCollector legit, stolen;
  Writer<msg::ScaleFactor> writer(identification, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile);
  Reader<msg::ScaleFactor> reader(dead_reckoning, topics::kScaleFactor.name, topics::kScaleFactor.reader_profile,
                                  [&](const msg::ScaleFactor& m) { legit.add(m); });
  Writer<msg::ScaleFactor> fake(rogue_writer_side, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile);
  Reader<msg::ScaleFactor> eavesdropper(rogue_reader_side, topics::kScaleFactor.name,
                                        topics::kGroundBestEffortReaderProfile,
                                        [&](const msg::ScaleFactor& m) { stolen.add(m); });
  ASSERT_TRUE(writer.wait_for_matched(1, kMatchTimeout));

  constexpr double kLegitK = 0.0508;
  constexpr double kFakeK = 9.99;
  // 3 s of both writing at 10 Hz: long enough for any (failed) handshake to have finished.
  for (int i = 0; i < 30; ++i) {
    writer.write(scale_factor(kLegitK, 200.0 + 0.1 * i));
    fake.write(scale_factor(kFakeK, 200.0 + 0.1 * i));
    std::this_thread::sleep_for(100ms);
  }
  const auto got = legit.values();
  ASSERT_FALSE(got.empty()) << "the legitimate reader received nothing from the legitimate writer";
  for (double k : got) EXPECT_EQ(k, kLegitK) << "a fake scale factor reached the legitimate reader";
  // The two rogues authenticate with each other (same foreign CA): the eavesdropper gets the fake
  // samples, which shows it is alive on the same network, yet not one legitimate sample.
  const auto overheard = stolen.values();
  EXPECT_FALSE(overheard.empty()) << "control: the rogue reader should hear its own accomplice";
  for (double k : overheard) EXPECT_EQ(k, kFakeK) << "the foreign-CA participant received a legitimate sample";
  EXPECT_EQ(fake.matched_readers(), 1u);          // its accomplice only
  EXPECT_EQ(eavesdropper.matched_writers(), 1u);  // its accomplice only
  EXPECT_EQ(writer.matched_readers(), 1u);        // the legitimate reader only
  EXPECT_EQ(reader.matched_writers(), 1u);        // the legitimate writer only
}

TEST_F(DdsSecurity, ParticipantWithoutCredentialsReceivesNothingAndCannotInject) {
  constexpr int kDomain = 73;
  ::unsetenv(odonav::dds::kSecurityDirEnv);
  Participant identification(secure_options(kDomain, "odonav-identification", pki_a()));
  Participant dead_reckoning(secure_options(kDomain, "odonav-dead-reckoning", pki_a()));
  Participant intruder(secure_options(kDomain, "intruder", ""));  // no security at all

  KCollector legit, stolen;
  Writer<msg::ScaleFactor> writer(identification, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile);
  Reader<msg::ScaleFactor> reader(dead_reckoning, topics::kScaleFactor.name, topics::kScaleFactor.reader_profile,
                                  [&](const msg::ScaleFactor& m) { legit.add(m); });
  Writer<msg::ScaleFactor> fake(intruder, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile);
  Reader<msg::ScaleFactor> eavesdropper(intruder, topics::kScaleFactor.name, topics::kGroundBestEffortReaderProfile,
                                        [&](const msg::ScaleFactor& m) { stolen.add(m); });
  ASSERT_TRUE(writer.wait_for_matched(1, kMatchTimeout));
  for (int i = 0; i < 30; ++i) {
    writer.write(scale_factor(0.0508, 300.0 + 0.1 * i));
    fake.write(scale_factor(9.99, 300.0 + 0.1 * i));
    std::this_thread::sleep_for(100ms);
  }
  const auto got = legit.values();
  ASSERT_FALSE(got.empty());
  for (double k : got) EXPECT_EQ(k, 0.0508) << "an unauthenticated scale factor reached the legitimate reader";
  // The intruder's reader matches its own writer (same participant) and nothing else.
  const auto overheard = stolen.values();
  EXPECT_FALSE(overheard.empty()) << "control: the intruder should hear its own writer";
  for (double k : overheard) EXPECT_EQ(k, 9.99) << "the unauthenticated participant received a legitimate sample";
  EXPECT_EQ(fake.matched_readers(), 1u);
  EXPECT_EQ(writer.matched_readers(), 1u);
  EXPECT_EQ(reader.matched_writers(), 1u);
}

TEST_F(DdsSecurity, PermissionsRefuseTopicsNotGranted) {
  constexpr int kDomain = 74;
  Participant calibration(secure_options(kDomain, "odonav-calibration", pki_a()));
  // Granted (positive control): its own estimate.
  EXPECT_NO_THROW(
      Writer<msg::Misalignment>(calibration, topics::kMisalignment.name, topics::kMisalignment.writer_profile));
  // Not granted: another component's estimate.
  const std::string writer_error = error_of(
      [&] { Writer<msg::ScaleFactor> w(calibration, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile); });
  EXPECT_NE(writer_error.find("rt/odonav/scale_factor"), std::string::npos) << writer_error;
  EXPECT_NE(writer_error.find("permissions of identity 'odonav-calibration'"), std::string::npos) << writer_error;
  EXPECT_NE(writer_error.find("do not allow publishing"), std::string::npos) << writer_error;

  // The ground station writes commands and nothing else, not even a scale factor.
  Participant ground(secure_options(kDomain, "odonav-ground", pki_a()));
  EXPECT_NO_THROW(Writer<msg::Command>(ground, topics::kCommand.name, topics::kCommand.writer_profile));
  EXPECT_NE(error_of([&] {
              Writer<msg::ScaleFactor> w(ground, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile);
            }).find("do not allow publishing"),
            std::string::npos);

  // Readers too: the gateway has no business reading the scale factor.
  Participant gateway(secure_options(kDomain, "odonav-gateway", pki_a()));
  const std::string reader_error = error_of(
      [&] { Reader<msg::ScaleFactor> r(gateway, topics::kScaleFactor.name, topics::kScaleFactor.reader_profile); });
  EXPECT_NE(reader_error.find("do not allow subscribing"), std::string::npos) << reader_error;
}

TEST_F(DdsSecurity, MissingOrMixedMaterialIsNamed) {
  constexpr int kDomain = 75;
  // A key file missing: the error names it before Fast DDS is asked.
  const fs::path broken = root_ / "broken";
  fs::remove_all(broken);
  fs::copy(pki_a(), broken, fs::copy_options::recursive);
  fs::remove(broken / "odonav-gateway/key.pem");
  const std::string missing = error_of([&] { Participant p(secure_options(kDomain, "odonav-gateway", broken)); });
  EXPECT_NE(missing.find("private key"), std::string::npos) << missing;
  EXPECT_NE(missing.find((broken / "odonav-gateway/key.pem").string()), std::string::npos) << missing;

  // An identity that does not exist in the directory.
  EXPECT_NE(error_of([&] {
              Participant p(secure_options(kDomain, "odonav-nobody", pki_a()));
            }).find("odonav-nobody/cert.pem"),
            std::string::npos);

  // Permissions signed by another permissions CA: Fast DDS refuses; the layer says what to check.
  const fs::path mixed = root_ / "mixed";
  fs::remove_all(mixed);
  fs::copy(pki_a(), mixed, fs::copy_options::recursive);
  fs::copy_file(pki_b() / "odonav-gateway/permissions.p7s", mixed / "odonav-gateway/permissions.p7s",
                fs::copy_options::overwrite_existing);
  const std::string refused = error_of([&] { Participant p(secure_options(kDomain, "odonav-gateway", mixed)); });
  EXPECT_NE(refused.find("DDS Security refused it"), std::string::npos) << refused;
  EXPECT_NE(refused.find("RFC 2253"), std::string::npos) << refused;
}
