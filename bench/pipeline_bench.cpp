// odonav-bench-pipeline: latency, CPU and memory of the distributed pipeline, to check the component
// budgets on a real host (BENCHMARKS.md §6).
//
// Runs odonav-gateway (replay of a simulated dataset), odonav-calibration, odonav-identification and
// odonav-dead-reckoning as separate processes on one host over the loopback profile, and measures:
//  (a) end-to-end latency: for each DeadReckoning output, the time this process received it minus the
//      time this process received the Odometer sample with the same stamp (the output's stamp IS the
//      odometer sample time). Both receive times come from one steady clock in one process, and the
//      reception hop (gateway -> here, DR -> here) is the same kind of hop on both sides, so it cancels:
//      what remains is "gateway publication -> DR publication" with no cross-process clock at all.
//      Also split: the time after the LAST input the DR output needed was received here (the output is
//      final only once INS and GNSS are at or past its time and the estimates of the GNSS epoch at or
//      before it arrived: components/dead_reckoning/README.md, "Event time");
//  (b) in the same run, the raw latency of one Fast DDS hop with the same transport and QoS: a ping
//      (Odometer type, odonav_sensor_writer / _reader profiles) to a child echo process and back at
//      the odometer rate, one hop = round trip / 2 (again one clock, one process);
//  (c) CPU % of each component over the data period (utime + stime from /proc/<pid>/stat) and its
//      peak RSS (VmHWM from /proc/<pid>/status, sampled during the run), at nominal real time and at 10x;
//  (d) the maximum replay rate sustained with nothing lost: a ladder of --speed values; a run loses
//      nothing when every DR output and the final samples_accepted of the identification equal those
//      of odonav-offline on the same dataset (the components are deterministic and equal to it).
//
// A benchmark, not a test: it prints figures and gates nothing (exit status 0 unless it could not run).
// Every child is killed (SIGKILL after a bounded wait) on every path out; only loopback DDS is used.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/logging.hpp"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/InsAttitude.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/Odometer.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/topics.hpp"

extern char** environ;

namespace {

constexpr const char* kProgram = "odonav-bench-pipeline";
constexpr const char* kPingTopic = "rt/odonav_bench/ping";
constexpr const char* kPongTopic = "rt/odonav_bench/pong";
// Hops on the path that releases a DR output: gateway -> identification (GNSS) -> DR (ScaleFactor);
// the odometer sample itself takes gateway -> DR, one hop, in parallel.
constexpr int kCriticalPathHops = 2;

int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// A header stamp as integer nanoseconds: the exact key that matches a DR output to its odometer sample.
int64_t stamp_ns(const std_msgs::msg::Header& h) {
  return static_cast<int64_t>(h.stamp().sec()) * 1000000000LL + static_cast<int64_t>(h.stamp().nanosec());
}

// ---- child processes --------------------------------------------------------------------------------

// One child process (posix_spawn, stdout and stderr to a log file). The destructor SIGKILLs and reaps
// it if it still runs, so no path out of the benchmark leaves an orphan.
class Child {
 public:
  Child(std::string name, const std::string& path, const std::vector<std::string>& args, const std::string& log)
      : name_(std::move(name)) {
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(path.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    const int rc = posix_spawn(&pid_, path.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) throw std::runtime_error("cannot start " + path + ": " + std::strerror(rc));
  }
  ~Child() {
    if (!reaped_) {
      ::kill(pid_, SIGKILL);
      reap_blocking();
    }
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  const std::string& name() const { return name_; }
  pid_t pid() const { return pid_; }
  bool reaped() const { return reaped_; }
  void signal(int sig) const {
    if (!reaped_) ::kill(pid_, sig);
  }
  // Non-blocking: true once the child has exited (then exit_code() and usage are valid).
  bool poll() {
    if (reaped_) return true;
    int status = 0;
    struct rusage usage {};
    if (wait4(pid_, &status, WNOHANG, &usage) == pid_) record(status, usage);
    return reaped_;
  }
  // Waits up to timeout_s for the exit; SIGKILL after that. True if it exited by itself.
  bool wait_exit(double timeout_s) {
    const int64_t end = steady_ns() + static_cast<int64_t>(timeout_s * 1e9);
    while (!poll()) {
      if (steady_ns() > end) {
        ::kill(pid_, SIGKILL);
        reap_blocking();
        return false;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return true;
  }
  int exit_code() const { return exit_code_; }
  double cpu_s() const { return cpu_s_; }      // user + system CPU of the whole life (after reaping)
  long max_rss_kb() const { return max_rss_kb_; }  // peak resident set (VmHWM), kB (after reaping)

 private:
  void reap_blocking() {
    int status = 0;
    struct rusage usage {};
    if (wait4(pid_, &status, 0, &usage) == pid_) record(status, usage);
    reaped_ = true;
  }
  void record(int status, const struct rusage& usage) {
    reaped_ = true;
    exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    cpu_s_ = static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
             1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
    max_rss_kb_ = usage.ru_maxrss;
  }
  std::string name_;
  pid_t pid_ = -1;
  bool reaped_ = false;
  int exit_code_ = -1;
  double cpu_s_ = 0.0;
  long max_rss_kb_ = 0;
};

// utime + stime of a running process from /proc/<pid>/stat [s]; NaN if it cannot be read.
// VmHWM (peak resident set) of a running process from /proc/<pid>/status [kB]; 0 if unreadable.
// Not ru_maxrss: Linux carries it across exec, so a spawned child would report this process's size.
long proc_hwm_kb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::atol(line.c_str() + 6);
  return 0;
}

double proc_cpu_s(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto paren = text.rfind(')');  // the command name may hold spaces: fields start after ')'
  if (paren == std::string::npos) return std::numeric_limits<double>::quiet_NaN();
  std::istringstream fields(text.substr(paren + 2));
  std::string f;
  unsigned long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && fields >> f; ++i) {  // field 3 is the state; 14 utime, 15 stime
    if (i == 14) utime = std::stoull(f);
    if (i == 15) stime = std::stoull(f);
  }
  return static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

std::string load_average() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return a + " " + b + " " + c;
}

// ---- what this process receives -----------------------------------------------------------------------

// (stamp, receive time) of one topic, in arrival order; thread-safe.
class Arrivals {
 public:
  void add(int64_t stamp, int64_t recv, uint32_t value = 0) {
    std::lock_guard<std::mutex> lock(mutex_);
    rows_.push_back(Row{stamp, recv, value});
  }
  struct Row {
    int64_t stamp_ns;
    int64_t recv_ns;
    uint32_t value;  // ScaleFactor: samples_accepted
  };
  std::vector<Row> rows() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return rows_;
  }
  std::size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return rows_.size();
  }

 private:
  mutable std::mutex mutex_;
  std::vector<Row> rows_;
};

// Rows sorted by stamp, keeping the first arrival of each stamp.
std::vector<Arrivals::Row> by_stamp(std::vector<Arrivals::Row> rows) {
  std::stable_sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.stamp_ns < b.stamp_ns; });
  rows.erase(std::unique(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.stamp_ns == b.stamp_ns; }),
             rows.end());
  return rows;
}

// Earliest receive time of a row with stamp >= t (rows sorted by stamp); nullopt-like -1 if none.
int64_t first_recv_at_or_after(const std::vector<Arrivals::Row>& rows, int64_t t) {
  auto it = std::lower_bound(rows.begin(), rows.end(), t, [](const auto& r, int64_t v) { return r.stamp_ns < v; });
  int64_t best = -1;
  // Arrival order follows stamp order (one writer each, in time order); the min guards reordering.
  for (int n = 0; it != rows.end() && n < 4; ++it, ++n)
    if (best < 0 || it->recv_ns < best) best = it->recv_ns;
  return best;
}

struct Percentiles {
  std::size_t n = 0;
  double p50 = 0, p99 = 0, max = 0;
};

// Nearest-rank percentiles of values given in ns, returned in ms.
Percentiles percentiles_ms(std::vector<int64_t> values_ns) {
  Percentiles p;
  p.n = values_ns.size();
  if (values_ns.empty()) return p;
  std::sort(values_ns.begin(), values_ns.end());
  auto rank = [&](double q) {
    const auto k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(values_ns.size())));
    return static_cast<double>(values_ns[std::min(values_ns.size() - 1, k == 0 ? 0 : k - 1)]) * 1e-6;
  };
  p.p50 = rank(0.50);
  p.p99 = rank(0.99);
  p.max = static_cast<double>(values_ns.back()) * 1e-6;
  return p;
}

std::string format_ms(const Percentiles& p) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(3) << "p50 " << p.p50 << " ms, p99 " << p.p99 << " ms, max " << p.max
    << " ms (n = " << p.n << ")";
  return s.str();
}

// ---- the echo child of the raw-hop measurement ----------------------------------------------------------

int run_echo(const odonav::dds::ParticipantOptions& participant_options, double run_s) {
  odonav::dds::Participant participant(participant_options);
  odonav::dds::Writer<odonav::msg::Odometer> pong(participant, kPongTopic, odonav::topics::kSensorWriterProfile);
  // Answer from the listener thread: a hand-over to another thread would add its wake-up to the hop.
  odonav::dds::Reader<odonav::msg::Odometer> ping(participant, kPingTopic, odonav::topics::kSensorReaderProfile,
                                                  [&pong](const odonav::msg::Odometer& m) { pong.write(m); });
  std::this_thread::sleep_for(std::chrono::duration<double>(run_s));  // the parent stops it with SIGKILL
  return 0;
}

// ---- one pipeline run -----------------------------------------------------------------------------------

struct Reference {  // odonav-offline on the same dataset
  std::size_t dr_outputs = 0;
  uint64_t samples_accepted = 0;
};

struct ComponentFigures {
  std::string name;
  double cpu_percent = 0.0;  // over the data period, % of one core
  double rss_mb = 0.0;       // peak RSS, MB (1e6 bytes)
  int exit_code = -1;
};

struct RunResult {
  std::string speed;
  bool completed = false;
  std::string failure;
  double data_wall_s = 0.0;  // first odometer sample .. gateway exit
  std::size_t samples_published = 0;
  double samples_per_s = 0.0;
  Percentiles end_to_end, after_last_input, hop;
  Percentiles end_to_end_steady, after_last_input_steady;  // outputs after the warm-up only
  std::vector<ComponentFigures> components;
  std::size_t dr_outputs = 0;
  uint64_t samples_accepted = 0;
  bool nothing_lost = false;
  std::string load_before, load_after;
};

struct Setup {
  std::string bin_dir;
  std::string self_path;
  std::string profile;
  std::string work;
  int domain = 140;
  double warmup_s = 10.0;  // data time excluded from the steady-state latency (standing start, first fixes)
  std::string vehicle_id = "bench-vehicle";
};

struct DatasetInfo {
  std::string dir;
  std::size_t odometer = 0, ins = 0, gnss = 0;
  double duration_s = 0.0;
  std::vector<std::string> component_flags;  // --lever-arm, --no-use-ins from meta.json (all three)
  std::vector<std::string> dead_reckoning_flags;  // --nominal-k from meta.json (DR only, as deploy/launch)
  Reference reference;
};

std::string shortest(double v) {
  std::ostringstream s;
  s << std::setprecision(17) << v;
  return s.str();
}

void shm_clean() { [[maybe_unused]] const int rc = std::system("fastdds shm clean >/dev/null 2>&1"); }

void run_or_throw(const std::string& what, const std::string& command) {
  if (std::system(command.c_str()) != 0) throw std::runtime_error(what + " failed: " + command);
}

// Index of a column in a CSV header line; throws naming the file when absent.
std::size_t column_index(const std::string& header, const std::string& name, const std::string& file) {
  std::stringstream cols(header);
  std::size_t i = 0;
  for (std::string c; std::getline(cols, c, ','); ++i) {
    c.erase(0, c.find_first_not_of(" \t"));
    c.erase(c.find_last_not_of(" \t\r") + 1);
    if (c == name) return i;
  }
  throw std::runtime_error(file + ": no column '" + name + "'");
}

Reference offline_reference(const Setup& setup, const std::string& dataset, const std::string& out) {
  run_or_throw("odonav-offline", "'" + setup.bin_dir + "/odonav-offline' '" + dataset + "' --out '" + out +
                                     "' --log-level warn >'" + out + ".log' 2>&1");
  Reference ref;
  std::string line, header;
  {
    const std::string file = out + "/dead_reckoning.csv";
    std::ifstream in(file);
    if (!in) throw std::runtime_error("cannot read " + file);
    while (std::getline(in, line)) {
      if (line.empty() || line[0] == '#') continue;
      if (header.empty()) header = line;
      else ++ref.dr_outputs;
    }
  }
  const std::string file = out + "/scale_factor.csv";
  std::ifstream in(file);
  if (!in) throw std::runtime_error("cannot read " + file);
  header.clear();
  std::string last;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (header.empty()) header = line;
    else last = line;
  }
  const std::size_t col = column_index(header, "samples_accepted", file);
  std::stringstream fields(last);
  std::string f;
  for (std::size_t i = 0; i <= col && std::getline(fields, f, ','); ++i) {
  }
  ref.samples_accepted = f.empty() ? 0 : std::stoull(f);
  return ref;
}

DatasetInfo make_dataset(const Setup& setup, const std::string& scenario, int64_t seed, double duration_s) {
  DatasetInfo info;
  std::ostringstream name;
  name << scenario << "-" << seed << "-" << duration_s << "s";
  info.dir = setup.work + "/" + name.str();
  run_or_throw("odonav-sim", "'" + setup.bin_dir + "/odonav-sim' " + scenario + " --seed " + std::to_string(seed) +
                                 " --duration-s " + shortest(duration_s) + " --out '" + info.dir +
                                 "' --log-level warn >'" + info.dir + ".log' 2>&1");
  const odonav::Dataset d = odonav::read_dataset(info.dir, odonav::BadRowPolicy::kFail);
  info.odometer = d.odometer.size();
  info.ins = d.ins.size();
  info.gnss = d.gnss.size();
  info.duration_s = d.odometer.empty() ? 0.0 : d.odometer.back().t_s - d.odometer.front().t_s;
  if (const auto& arm = d.meta.gnss_lever_arm_m)
    info.component_flags = {"--lever-arm", shortest(arm->x()) + "," + shortest(arm->y()) + "," + shortest(arm->z())};
  if (const auto& k = d.meta.k_nominal_m_per_pulse) {
    info.dead_reckoning_flags = {"--nominal-k", shortest(*k)};
  }
  if (!d.has_ins()) info.component_flags.push_back("--no-use-ins");
  info.reference = offline_reference(setup, info.dir, info.dir + "-offline");
  return info;
}

RunResult run_pipeline(const Setup& setup, const DatasetInfo& data, const std::string& speed) {
  RunResult result;
  result.speed = speed;
  result.load_before = load_average();
  const bool real_time = speed == "1";
  const double speed_factor = speed == "max" ? 0.0 : std::stod(speed);
  const std::string logs = setup.work + "/logs-" + speed;
  mkdir(logs.c_str(), 0755);
  shm_clean();

  odonav::dds::ParticipantOptions po;
  po.profiles_file = setup.profile;
  po.domain_id = setup.domain;
  po.participant_name = kProgram;
  auto participant = std::make_unique<odonav::dds::Participant>(po);
  namespace t = odonav::topics;
  Arrivals odometer, ins, gnss, scale_factor, misalignment, dead_reckoning, pong_rtt;
  using odonav::msg::DeadReckoning;
  using odonav::msg::GnssFix;
  using odonav::msg::InsAttitude;
  using odonav::msg::Misalignment;
  using odonav::msg::Odometer;
  using odonav::msg::ScaleFactor;
  // Receive times are taken first thing in each callback (Fast DDS listener threads).
  odonav::dds::Reader<Odometer> odometer_reader(*participant, t::kOdometer.name, t::kOdometer.reader_profile,
                                                [&](const Odometer& m) { odometer.add(stamp_ns(m.header()), steady_ns()); });
  odonav::dds::Reader<InsAttitude> ins_reader(*participant, t::kInsAttitude.name, t::kInsAttitude.reader_profile,
                                              [&](const InsAttitude& m) { ins.add(stamp_ns(m.header()), steady_ns()); });
  odonav::dds::Reader<GnssFix> gnss_reader(*participant, t::kGnssFix.name, t::kGnssFix.reader_profile,
                                           [&](const GnssFix& m) { gnss.add(stamp_ns(m.header()), steady_ns()); });
  odonav::dds::Reader<ScaleFactor> sf_reader(
      *participant, t::kScaleFactor.name, t::kScaleFactor.reader_profile, [&](const ScaleFactor& m) {
        scale_factor.add(stamp_ns(m.header()), steady_ns(), m.samples_accepted());
      });
  odonav::dds::Reader<Misalignment> mis_reader(
      *participant, t::kMisalignment.name, t::kMisalignment.reader_profile,
      [&](const Misalignment& m) { misalignment.add(stamp_ns(m.header()), steady_ns()); });
  odonav::dds::Reader<DeadReckoning> dr_reader(
      *participant, t::kDeadReckoning.name, t::kDeadReckoning.reader_profile,
      [&](const DeadReckoning& m) { dead_reckoning.add(stamp_ns(m.header()), steady_ns()); });
  odonav::dds::Writer<Odometer> ping_writer(*participant, kPingTopic, t::kSensorWriterProfile);
  odonav::dds::Reader<Odometer> pong_reader(*participant, kPongTopic, t::kSensorReaderProfile,
                                            [&](const Odometer& m) {
                                              const int64_t now = steady_ns();
                                              pong_rtt.add(stamp_ns(m.header()), now);
                                            });

  const std::vector<std::string> common{"--domain",     std::to_string(setup.domain), "--profile", setup.profile,
                                        "--vehicle-id", setup.vehicle_id,             "--log-level", "warn"};
  // As deploy/launch: at real time an input silent 2 s is absent; faster, queues may lag more.
  std::vector<std::string> node = common;
  node.insert(node.end(), {"--max-wait-s", real_time ? "2" : "30"});
  node.insert(node.end(), data.component_flags.begin(), data.component_flags.end());
  std::vector<std::unique_ptr<Child>> components;
  const std::string bin = setup.bin_dir + "/";
  for (const std::string c : {"odonav-dead-reckoning", "odonav-identification", "odonav-calibration"}) {
    std::vector<std::string> args = node;
    if (c == "odonav-dead-reckoning")
      args.insert(args.end(), data.dead_reckoning_flags.begin(), data.dead_reckoning_flags.end());
    components.push_back(std::make_unique<Child>(c, bin + c, args, logs + "/" + c + ".log"));
  }
  auto echo_args = common;
  echo_args.insert(echo_args.begin(), "--echo");
  Child echo("echo", setup.self_path, echo_args, logs + "/echo.log");

  auto fail = [&](const std::string& why) {
    result.failure = why;
    for (auto& c : components) c->wait_exit(0.0);
    echo.wait_exit(0.0);
    participant.reset();
    shm_clean();
    return result;
  };
  // The components are up when their outputs matched this process's readers; the echo likewise.
  const int64_t match_deadline = steady_ns() + 60000000000LL;
  while (sf_reader.matched_writers() < 1 || mis_reader.matched_writers() < 1 || dr_reader.matched_writers() < 1 ||
         pong_reader.matched_writers() < 1 || ping_writer.matched_readers() < 1) {
    for (auto& c : components)
      if (c->poll()) return fail(c->name() + " exited at start with status " + std::to_string(c->exit_code()) +
                                 " (log: " + logs + "/" + c->name() + ".log)");
    if (echo.poll()) return fail("the echo process exited at start (log: " + logs + "/echo.log)");
    if (steady_ns() > match_deadline) return fail("components or echo not matched within 60 s (logs: " + logs + ")");
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::this_thread::sleep_for(std::chrono::seconds(1));  // their mutual matching, as the gateway waits for GNSS readers only

  const std::size_t odo_before = odometer.size();
  std::vector<std::string> gw = common;
  // Four GNSS readers: calibration, identification, dead reckoning and this process.
  gw.insert(gw.end(), {"--source", "replay:" + data.dir, "--speed", speed, "--wait-for-readers", "4"});
  Child gateway("odonav-gateway", bin + "odonav-gateway", gw, logs + "/odonav-gateway.log");

  // Pings at the odometer rate of this run (every 10 ms / speed; at most 1 kHz), from the first data on.
  std::atomic<bool> pinging{true};
  std::thread pinger([&] {
    const double period_s = speed_factor > 0.0 ? std::max(0.01 / speed_factor, 0.001) : 0.001;
    Odometer ping;
    ping.vehicle_id("bench-ping");
    while (pinging.load()) {
      const int64_t now = steady_ns();
      ping.header().stamp().sec(static_cast<int32_t>(now / 1000000000LL));
      ping.header().stamp().nanosec(static_cast<uint32_t>(now % 1000000000LL));
      ping_writer.write(ping);
      std::this_thread::sleep_for(std::chrono::duration<double>(period_s));
    }
  });
  auto stop_pinger = [&] {
    pinging = false;
    if (pinger.joinable()) pinger.join();
  };
  struct JoinOnExit {  // every path out (also an exception) stops the pinger before its writer goes
    std::function<void()> stop;
    ~JoinOnExit() { stop(); }
  } join_pinger{stop_pinger};

  // Data period: from the first odometer sample here to the gateway's exit.
  const double gateway_timeout_s = 120.0 + (speed_factor > 0.0 ? 1.5 * data.duration_s / speed_factor : data.duration_s);
  const int64_t start = steady_ns();
  int64_t data_start = -1;
  std::vector<double> cpu_at_start(components.size() + 1, 0.0);
  std::vector<long> hwm_kb(components.size() + 1, 0);
  auto sample_hwm = [&] {
    for (std::size_t i = 0; i < components.size(); ++i)
      hwm_kb[i] = std::max(hwm_kb[i], proc_hwm_kb(components[i]->pid()));
    if (!gateway.reaped()) hwm_kb.back() = std::max(hwm_kb.back(), proc_hwm_kb(gateway.pid()));
  };
  while (!gateway.poll()) {
    sample_hwm();
    if (data_start < 0 && odometer.size() > odo_before) {
      data_start = steady_ns();
      for (std::size_t i = 0; i < components.size(); ++i) cpu_at_start[i] = proc_cpu_s(components[i]->pid());
      cpu_at_start.back() = proc_cpu_s(gateway.pid());
    }
    for (auto& c : components)
      if (c->poll()) {
        stop_pinger();
        return fail(c->name() + " exited early with status " + std::to_string(c->exit_code()));
      }
    if (steady_ns() - start > static_cast<int64_t>(gateway_timeout_s * 1e9)) {
      stop_pinger();
      return fail("odonav-gateway did not finish within " + shortest(gateway_timeout_s) + " s");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(data_start < 0 ? 2 : 50));
  }
  const int64_t data_end = steady_ns();
  stop_pinger();
  if (gateway.exit_code() != 0 || data_start < 0)
    return fail("odonav-gateway exited with status " + std::to_string(gateway.exit_code()) +
                (data_start < 0 ? " before any data arrived" : ""));
  result.data_wall_s = static_cast<double>(data_end - data_start) * 1e-9;
  std::vector<double> cpu_at_end(components.size());
  for (std::size_t i = 0; i < components.size(); ++i) cpu_at_end[i] = proc_cpu_s(components[i]->pid());
  sample_hwm();

  // Let the components drain what they hold, then stop them in data-flow order (as deploy/launch).
  for (std::size_t last = 0, stable_polls = 0; stable_polls < 10;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    const std::size_t now = dead_reckoning.size();
    stable_polls = now == last ? stable_polls + 1 : 0;
    last = now;
  }
  for (const char* name : {"odonav-calibration", "odonav-identification", "odonav-dead-reckoning"})
    for (auto& c : components)
      if (c->name() == name) {
        c->signal(SIGINT);
        if (!c->wait_exit(60.0)) return fail(c->name() + " did not stop within 60 s of SIGINT");
      }
  echo.wait_exit(0.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // last DR outputs of finish()
  result.load_after = load_average();

  // ---- figures ----
  const double data_s = result.data_wall_s;
  for (std::size_t i = 0; i < components.size(); ++i) {
    const auto& c = *components[i];
    result.components.push_back(ComponentFigures{c.name(), 100.0 * (cpu_at_end[i] - cpu_at_start[i]) / data_s,
                                                 static_cast<double>(hwm_kb[i]) * 1024e-6, c.exit_code()});
  }
  // The gateway's CPU: its whole life (reaped) minus what it used before the first sample.
  result.components.push_back(ComponentFigures{"odonav-gateway", 100.0 * (gateway.cpu_s() - cpu_at_start.back()) / data_s,
                                               static_cast<double>(hwm_kb.back()) * 1024e-6, gateway.exit_code()});
  result.samples_published = data.odometer + data.ins + data.gnss;

  const auto odo = by_stamp(odometer.rows());
  const auto ins_rows = by_stamp(ins.rows());
  const auto gnss_rows = by_stamp(gnss.rows());
  const auto sf_rows = by_stamp(scale_factor.rows());
  const auto mis_rows = by_stamp(misalignment.rows());
  const auto dr_rows = by_stamp(dead_reckoning.rows());
  std::vector<int64_t> e2e, after_last, e2e_steady, after_last_steady;
  const int64_t steady_from = odo.empty() ? 0 : odo.front().stamp_ns + static_cast<int64_t>(setup.warmup_s * 1e9);
  for (const auto& dr : dr_rows) {
    const auto it = std::lower_bound(odo.begin(), odo.end(), dr.stamp_ns,
                                     [](const auto& r, int64_t v) { return r.stamp_ns < v; });
    if (it == odo.end() || it->stamp_ns != dr.stamp_ns) continue;
    e2e.push_back(dr.recv_ns - it->recv_ns);
    // The GNSS epoch at or before t: its estimates must have arrived.
    auto g = std::upper_bound(gnss_rows.begin(), gnss_rows.end(), dr.stamp_ns,
                              [](int64_t v, const auto& r) { return v < r.stamp_ns; });
    int64_t release = it->recv_ns;
    for (int64_t r : {first_recv_at_or_after(ins_rows, dr.stamp_ns), first_recv_at_or_after(gnss_rows, dr.stamp_ns)})
      release = std::max(release, r);
    if (g != gnss_rows.begin()) {
      const int64_t epoch = std::prev(g)->stamp_ns;
      for (int64_t r : {first_recv_at_or_after(sf_rows, epoch), first_recv_at_or_after(mis_rows, epoch)})
        release = std::max(release, r);
    }
    after_last.push_back(dr.recv_ns - release);
    if (dr.stamp_ns >= steady_from) {
      e2e_steady.push_back(e2e.back());
      after_last_steady.push_back(after_last.back());
    }
  }
  result.end_to_end_steady = percentiles_ms(e2e_steady);
  result.after_last_input_steady = percentiles_ms(after_last_steady);
  // Offered rate: the samples over the span the odometer stream took to arrive here.
  if (odo.size() > 1) {
    const auto [first, last] = std::minmax_element(odo.begin(), odo.end(),
                                                   [](const auto& a, const auto& b) { return a.recv_ns < b.recv_ns; });
    result.samples_per_s = static_cast<double>(data.odometer + data.ins + data.gnss) /
                           (static_cast<double>(last->recv_ns - first->recv_ns) * 1e-9);
  }
  result.end_to_end = percentiles_ms(e2e);
  result.after_last_input = percentiles_ms(after_last);
  std::vector<int64_t> hop;
  for (const auto& r : pong_rtt.rows()) hop.push_back((r.recv_ns - r.stamp_ns) / 2);
  result.hop = percentiles_ms(hop);
  result.dr_outputs = dr_rows.size();
  result.samples_accepted = 0;
  for (const auto& r : sf_rows) result.samples_accepted = std::max<uint64_t>(result.samples_accepted, r.value);
  // This process's own odometer reader may miss the first sample (matched last): not a pipeline loss.
  result.nothing_lost = result.dr_outputs == data.reference.dr_outputs &&
                        result.samples_accepted == data.reference.samples_accepted;
  result.completed = true;
  participant.reset();
  shm_clean();
  return result;
}

void print_run(std::ostream& out, const RunResult& r, const DatasetInfo& data, double warmup_s) {
  out << "\n### speed " << r.speed << " (" << data.dir << ")\n";
  if (!r.completed) {
    out << "FAILED: " << r.failure << "\n";
    return;
  }
  out << std::fixed << std::setprecision(1);
  out << "load average before / after: " << r.load_before << " / " << r.load_after << "\n";
  out << "data period " << std::setprecision(2) << r.data_wall_s << " s wall, " << r.samples_published
      << " samples published, " << std::setprecision(0) << r.samples_per_s
      << " samples/s (over the span of the odometer stream's arrival here)\n";
  out << "end-to-end (gateway publication of an odometer sample -> DR output with its stamp): "
      << format_ms(r.end_to_end) << "\n";
  out << "  of which after the last input the output needed was received: " << format_ms(r.after_last_input) << "\n";
  out << "steady state (outputs after the first " << std::setprecision(0) << warmup_s << " s of data): end-to-end "
      << format_ms(r.end_to_end_steady) << "\n  after the last input: " << format_ms(r.after_last_input_steady) << "\n";
  out << "raw Fast DDS hop (ping-pong / 2, same transport and QoS, same run): " << format_ms(r.hop) << "\n";
  if (r.hop.p99 > 0.0)
    out << std::setprecision(1) << "ratios (steady state): end-to-end p99 / (" << kCriticalPathHops
        << " hops x raw hop p99) = " << r.end_to_end_steady.p99 / (kCriticalPathHops * r.hop.p99)
        << "; after-last-input p99 / raw hop p99 = " << r.after_last_input_steady.p99 / r.hop.p99 << "\n";
  out << "| component | CPU % of one core (data period) | peak RSS (MB) | exit |\n|---|---|---|---|\n";
  double total_cpu = 0.0, total_no_gateway = 0.0;
  for (const auto& c : r.components) {
    out << "| " << c.name << " | " << std::setprecision(2) << c.cpu_percent << " | " << std::setprecision(1) << c.rss_mb
        << " | " << c.exit_code << " |\n";
    total_cpu += c.cpu_percent;
    if (c.name != "odonav-gateway") total_no_gateway += c.cpu_percent;
  }
  out << "| all four | " << std::setprecision(2) << total_cpu << " | | |\n";
  out << "(the three consumers alone: " << total_no_gateway << " %)\n";
  out << "DR outputs " << r.dr_outputs << " / " << data.reference.dr_outputs << " (odonav-offline); samples_accepted "
      << r.samples_accepted << " / " << data.reference.samples_accepted << ": "
      << (r.nothing_lost ? "nothing lost" : "LOST DATA") << "\n";
}

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream s(text);
  for (std::string item; std::getline(s, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

std::string self_path(const char* argv0) {
  char buffer[4096];
  const ssize_t n = readlink("/proc/self/exe", buffer, sizeof(buffer) - 1);
  if (n > 0) return std::string(buffer, static_cast<std::size_t>(n));
  return argv0;
}

}  // namespace

int main(int argc, char** argv) {
  odonav::Options opts(kProgram,
                       "Pipeline benchmark: gateway + calibration + identification + dead reckoning as "
                       "processes over loopback DDS; end-to-end latency against the raw hop, CPU and peak RSS per "
                       "component, and the highest replay speed with nothing lost. Prints figures. Not a test.");
  opts.add_int("domain", 140, "DDS domain id of the runs", 0, 232);
  opts.add_string("profile", "", "loopback participant profile (default: <source>/deploy/profiles/loopback.xml)");
  opts.add_string("bin-dir", "", "directory of the odonav executables (default: this executable's)");
  opts.add_string("work", "", "datasets, outputs and logs (default: $TMPDIR or /tmp, under odonav-bench/pipeline)");
  opts.add_string("scenario", "terrain", "simulated scenario of the datasets (straight, ring, terrain)");
  opts.add_int("seed", 1, "simulator seed", 0, 1000000);
  opts.add_double("nominal-duration-s", 60.0, "data length of the real-time run, s", 5.0, 3600.0);
  opts.add_double("fast-duration-s", 600.0, "data length of the 10x run and of the ladder, s", 10.0, 3600.0);
  opts.add_string("speeds", "1,10", "speeds measured in full (latency, CPU, RSS); 1 uses the nominal dataset");
  opts.add_string("ladder", "20,50,100,200,max",
                  "replay speeds tried for (d) in increasing order on the fast dataset; stops at the first loss");
  opts.add_double("warmup-s", 10.0, "data time at the start left out of the steady-state latency, s", 0.0, 3600.0);
  opts.add_bool("echo", false, "internal: run as the echo process of the raw-hop measurement");
  opts.add_string("vehicle-id", "bench-vehicle", "vehicle id of the run (the DDS key)");
  opts.add_string("log-level", "warn", "trace, debug, info, warn, error, critical, off");
  Setup setup;
  try {
    if (opts.parse(argc, argv) == odonav::ParseResult::kHelp) return 0;
    odonav::setup_logging("bench-pipeline", opts.get_string("log-level"));
    setup.self_path = self_path(argv[0]);
    setup.bin_dir = opts.get_string("bin-dir");
    if (setup.bin_dir.empty()) setup.bin_dir = setup.self_path.substr(0, setup.self_path.rfind('/'));
    setup.profile = opts.get_string("profile");
    if (setup.profile.empty()) setup.profile = std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/loopback.xml";
    setup.domain = static_cast<int>(opts.get_int("domain"));
    setup.vehicle_id = opts.get_string("vehicle-id");
    setup.warmup_s = opts.get_double("warmup-s");
    if (setup.vehicle_id.empty()) throw odonav::ConfigError("--vehicle-id: must not be empty");
    for (const auto& s : split(opts.get_string("speeds")) ) {
      if (s == "max") continue;
      char* end = nullptr;
      const double v = std::strtod(s.c_str(), &end);
      if (end == s.c_str() || *end != '\0' || !(v > 0.0))
        throw odonav::ConfigError("--speeds: '" + s + "' is not a positive number or max");
    }
    for (const auto& s : split(opts.get_string("ladder"))) {
      if (s == "max") continue;
      char* end = nullptr;
      const double v = std::strtod(s.c_str(), &end);
      if (end == s.c_str() || *end != '\0' || !(v > 0.0))
        throw odonav::ConfigError("--ladder: '" + s + "' is not a positive number or max");
    }
  } catch (const odonav::ConfigError& e) {
    std::cerr << kProgram << ": " << e.what() << "\n";
    return 2;
  }
  // Loopback only, and no stray XML in the working directory (docs/DDS.md §2).
  setenv("FASTRTPS_DEFAULT_PROFILES_FILE", setup.profile.c_str(), 1);
  setenv("SKIP_DEFAULT_XML", "1", 1);
  signal(SIGPIPE, SIG_IGN);

  if (opts.get_bool("echo")) {
    odonav::dds::ParticipantOptions po;
    po.profiles_file = setup.profile;
    po.domain_id = setup.domain;
    po.participant_name = "odonav-bench-echo";
    try {
      return run_echo(po, 3600.0);
    } catch (const std::exception& e) {
      std::cerr << kProgram << " --echo: " << e.what() << "\n";
      return 1;
    }
  }

  try {
    std::string work = opts.get_string("work");
    if (work.empty()) {
      const char* tmp = std::getenv("TMPDIR");
      work = std::string(tmp && *tmp ? tmp : "/tmp") + "/odonav-bench/pipeline";
    }
    run_or_throw("mkdir", "mkdir -p '" + work + "'");
    setup.work = work;
    const std::string scenario = opts.get_string("scenario");
    const int64_t seed = opts.get_int("seed");
    std::cout << "# odonav-bench-pipeline: " << std::thread::hardware_concurrency() << " cores, load "
              << load_average() << ", domain " << setup.domain << ", profile " << setup.profile << "\n";
    std::cout << "method: receive times in this process (steady clock): DR output minus odometer sample of the same "
                 "stamp; raw hop = ping-pong round trip / 2 to an echo process; CPU from /proc/<pid>/stat over the "
                 "data period; peak RSS = VmHWM from /proc/<pid>/status, sampled during the run\n";
    const DatasetInfo nominal = make_dataset(setup, scenario, seed, opts.get_double("nominal-duration-s"));
    const DatasetInfo fast = make_dataset(setup, scenario, seed, opts.get_double("fast-duration-s"));
    for (const DatasetInfo* d : {&nominal, &fast})
      std::cout << "dataset " << d->dir << ": " << d->odometer << " odometer, " << d->ins << " INS, " << d->gnss
                << " GNSS samples over " << d->duration_s << " s; odonav-offline: " << d->reference.dr_outputs
                << " DR outputs, " << d->reference.samples_accepted << " samples accepted\n";

    std::cout << "\n## (a)-(c) latency, CPU, RSS\n";
    for (const auto& s : split(opts.get_string("speeds"))) {
      const DatasetInfo& d = s == "1" ? nominal : fast;
      print_run(std::cout, run_pipeline(setup, d, s), d, setup.warmup_s);
      std::cout.flush();
    }
    std::cout << "\n## (d) highest replay speed with nothing lost (ladder on " << fast.dir << ")\n";
    std::string best = "none";
    double best_rate = 0.0;
    for (const auto& s : split(opts.get_string("ladder"))) {
      const RunResult r = run_pipeline(setup, fast, s);
      std::cout << "speed " << s << ": ";
      if (!r.completed) {
        std::cout << "FAILED: " << r.failure << "\n";
        break;
      }
      std::cout << std::fixed << std::setprecision(0) << r.samples_per_s << " samples/s over " << std::setprecision(2)
                << r.data_wall_s << " s (first odometer sample -> gateway exit); DR outputs " << r.dr_outputs << " / " << fast.reference.dr_outputs
                << ", samples_accepted " << r.samples_accepted << " / " << fast.reference.samples_accepted << ", steady e2e "
                << format_ms(r.end_to_end_steady) << ", load " << r.load_after << ": "
                << (r.nothing_lost ? "nothing lost" : "LOST DATA") << "\n";
      std::cout.flush();
      if (!r.nothing_lost) break;
      best = s;
      best_rate = std::max(best_rate, r.samples_per_s);
    }
    std::cout << "highest speed with nothing lost: " << best << " (" << std::setprecision(0) << best_rate
              << " samples/s)\n";
  } catch (const std::exception& e) {
    std::cerr << kProgram << ": " << e.what() << "\n";
    shm_clean();
    return 1;
  }
  return 0;
}
