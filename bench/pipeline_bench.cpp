// odonav-bench-pipeline: latency, CPU and memory of the distributed pipeline, to check the component
// budgets on a real host (BENCHMARKS.md §5).
//
// Runs odonav-gateway (replay of a simulated dataset), odonav-calibration, odonav-identification and
// odonav-dead-reckoning as separate processes on one host over the loopback profile, and measures:
//  (a) end-to-end latency: for each DeadReckoning output, the time this process received it minus the
//      time this process received the Odometer sample with the same stamp (the output's stamp IS the
//      odometer sample time). Both receive times come from one steady clock in one process, and the
//      reception hop (gateway -> here, DR -> here) is the same kind of hop on both sides, so it cancels:
//      what remains is "gateway publication -> DR publication" with no cross-process clock at all.
//      Also split: the time after the LAST input the DR output needed was received here: its odometer
//      sample, the INS at or past its time, and the GNSS fix and estimates (misalignment, K) of the
//      epochs up to its time minus the estimate hold-off (consumer_rules.hpp; the rule of
//      components/dead_reckoning/README.md, "Event time");
//      and the estimates' own latency: each Misalignment (calibration) and ScaleFactor
//      (identification) received here minus the GNSS fix of the same epoch received here;
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
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
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

#include "child_process.hpp"
#include "locked_vector.hpp"
#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/logging.hpp"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/InsAttitude.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/NavigationPosition.h"
#include "odonav/msg/Odometer.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/topics.hpp"

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

// A named child process (tests/support/child_process.hpp: posix_spawn, reaped with wait4 for its
// CPU time), stdout and stderr to a log file. Its destructor SIGKILLs and reaps it if it still
// runs, so no path out of the benchmark leaves an orphan.
class Child : public odonav::test::ChildProcess {
 public:
  Child(std::string name, const std::string& path, const std::vector<std::string>& args, const std::string& log)
      : ChildProcess(path, args, log, log), name_(std::move(name)) {
    if (!started()) throw std::runtime_error("cannot start " + path + ": " + std::strerror(spawn_error()));
  }
  const std::string& name() const { return name_; }

 private:
  std::string name_;
};

// VmHWM (peak resident set) of a running process from /proc/<pid>/status [kB]; 0 if unreadable.
// Not ru_maxrss: Linux carries it across exec, so a spawned child would report this process's size.
long proc_hwm_kb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::atol(line.c_str() + 6);
  return 0;
}

// utime + stime of a running process from /proc/<pid>/stat [s]; NaN if it cannot be read.
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

// Context switches (voluntary + involuntary) of all threads of a running process, from
// /proc/<pid>/task/*/status (/proc/<pid>/status counts the main thread only); -1 if unreadable.
long long proc_context_switches(pid_t pid) {
  const std::filesystem::path tasks = "/proc/" + std::to_string(pid) + "/task";
  std::error_code ec;
  long long total = 0;
  bool any = false;
  for (const auto& task : std::filesystem::directory_iterator(tasks, ec)) {
    std::ifstream in(task.path() / "status");
    for (std::string line; std::getline(in, line);)
      if (line.rfind("voluntary_ctxt_switches:", 0) == 0 || line.rfind("nonvoluntary_ctxt_switches:", 0) == 0) {
        total += std::atoll(line.c_str() + line.find(':') + 1);
        any = true;
      }
  }
  return any ? total : -1;
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
  struct Row {
    int64_t stamp_ns;
    int64_t recv_ns;
    uint32_t value;  // ScaleFactor: samples_accepted
  };
  void add(int64_t stamp, int64_t recv, uint32_t value = 0) { rows_.push_back(Row{stamp, recv, value}); }
  std::vector<Row> rows() const { return rows_.copy(); }
  std::size_t size() const { return rows_.size(); }

 private:
  odonav::test::LockedVector<Row> rows_;
};

// Rows sorted by stamp, keeping the first arrival of each stamp.
std::vector<Arrivals::Row> by_stamp(std::vector<Arrivals::Row> rows) {
  std::stable_sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.stamp_ns < b.stamp_ns; });
  rows.erase(
      std::unique(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.stamp_ns == b.stamp_ns; }),
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
  double cpu_percent = 0.0;     // over the data period, % of one core
  double rss_mb = 0.0;          // peak RSS, MB (1e6 bytes)
  double switches_per_s = 0.0;  // context switches of all its threads over the data period, per second
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
  Percentiles end_to_end_steady, after_last_input_steady;         // outputs after the warm-up only
  Percentiles calibration_after_gnss, identification_after_gnss;  // estimate received - its GNSS received
  Percentiles navigation_end_to_end_steady;  // anchored position received - its odometer sample received
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
  double warmup_s = 10.0;      // data time excluded from the steady-state latency (standing start, first fixes)
  double gnss_rate_hz = 10.0;  // odonav-simulator --gnss-rate
  double hold_off_s = 0.2;     // the components' --estimate-hold-off-s (given to them when pass_hold_off)
  bool pass_hold_off = false;
  std::string vehicle_id = "bench-vehicle";
};

struct DatasetInfo {
  std::string dir;
  std::size_t odometer = 0, ins = 0, gnss = 0;
  double duration_s = 0.0;
  std::vector<std::string> component_flags;       // --lever-arm, --no-use-ins from meta.json (all three)
  std::vector<std::string> dead_reckoning_flags;  // --nominal-k from meta.json (DR only, as deploy/launch)
  Reference reference;
};

std::string shortest(double v) {
  std::ostringstream s;
  s << std::setprecision(17) << v;
  return s.str();
}

using odonav::test::shm_clean;

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
  const std::string hold = setup.pass_hold_off ? " --estimate-hold-off-s " + shortest(setup.hold_off_s) : "";
  run_or_throw("odonav-offline", "'" + setup.bin_dir + "/odonav-offline' '" + dataset + "' --out '" + out + "'" + hold +
                                     " --log-level warn >'" + out + ".log' 2>&1");
  Reference ref;
  std::string line, header;
  {
    const std::string file = out + "/dead_reckoning.csv";
    std::ifstream in(file);
    if (!in) throw std::runtime_error("cannot read " + file);
    while (std::getline(in, line)) {
      if (line.empty() || line[0] == '#') continue;
      if (header.empty())
        header = line;
      else
        ++ref.dr_outputs;
    }
  }
  const std::string file = out + "/scale_factor.csv";
  std::ifstream in(file);
  if (!in) throw std::runtime_error("cannot read " + file);
  header.clear();
  std::string last;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (header.empty())
      header = line;
    else
      last = line;
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
  name << scenario << "-" << seed << "-" << duration_s << "s-" << setup.gnss_rate_hz << "hz";
  info.dir = setup.work + "/" + name.str();
  run_or_throw("odonav-simulator", "'" + setup.bin_dir + "/odonav-simulator' " + scenario + " --seed " +
                                       std::to_string(seed) + " --duration-s " + shortest(duration_s) +
                                       " --gnss-rate " + shortest(setup.gnss_rate_hz) + " --out '" + info.dir +
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

using odonav::msg::DeadReckoning;
using odonav::msg::GnssFix;
using odonav::msg::InsAttitude;
using odonav::msg::Misalignment;
using odonav::msg::Odometer;
using odonav::msg::ScaleFactor;

// This process's readers of the pipeline's topics, with the receive times taken first thing in each
// callback (Fast DDS listener threads), and the ping writer / pong reader of the raw-hop measurement.
struct Probes {
  Arrivals odometer, ins, gnss, scale_factor, misalignment, dead_reckoning, navigation, pong_rtt;
  odonav::dds::Reader<Odometer> odometer_reader;
  odonav::dds::Reader<InsAttitude> ins_reader;
  odonav::dds::Reader<GnssFix> gnss_reader;
  odonav::dds::Reader<ScaleFactor> sf_reader;
  odonav::dds::Reader<Misalignment> mis_reader;
  odonav::dds::Reader<DeadReckoning> dr_reader;
  odonav::dds::Reader<odonav::msg::NavigationPosition> nav_reader;
  odonav::dds::Writer<Odometer> ping_writer;
  odonav::dds::Reader<Odometer> pong_reader;

  explicit Probes(odonav::dds::Participant& p)
      : odometer_reader(p, odonav::topics::kOdometer.name, odonav::topics::kOdometer.reader_profile,
                        [this](const Odometer& m) { odometer.add(stamp_ns(m.header()), steady_ns()); }),
        ins_reader(p, odonav::topics::kInsAttitude.name, odonav::topics::kInsAttitude.reader_profile,
                   [this](const InsAttitude& m) { ins.add(stamp_ns(m.header()), steady_ns()); }),
        gnss_reader(p, odonav::topics::kGnssFix.name, odonav::topics::kGnssFix.reader_profile,
                    [this](const GnssFix& m) { gnss.add(stamp_ns(m.header()), steady_ns()); }),
        sf_reader(p, odonav::topics::kScaleFactor.name, odonav::topics::kScaleFactor.reader_profile,
                  [this](const ScaleFactor& m) {
                    scale_factor.add(stamp_ns(m.header()), steady_ns(), m.samples_accepted());
                  }),
        mis_reader(p, odonav::topics::kMisalignment.name, odonav::topics::kMisalignment.reader_profile,
                   [this](const Misalignment& m) { misalignment.add(stamp_ns(m.header()), steady_ns()); }),
        dr_reader(p, odonav::topics::kDeadReckoning.name, odonav::topics::kDeadReckoning.reader_profile,
                  [this](const DeadReckoning& m) { dead_reckoning.add(stamp_ns(m.header()), steady_ns()); }),
        nav_reader(
            p, odonav::topics::kNavigationPosition.name, odonav::topics::kNavigationPosition.reader_profile,
            [this](const odonav::msg::NavigationPosition& m) { navigation.add(stamp_ns(m.header()), steady_ns()); }),
        ping_writer(p, kPingTopic, odonav::topics::kSensorWriterProfile),
        pong_reader(p, kPongTopic, odonav::topics::kSensorReaderProfile, [this](const Odometer& m) {
          const int64_t now = steady_ns();
          pong_rtt.add(stamp_ns(m.header()), now);
        }) {}

  // The components and the echo are up when their outputs matched these readers.
  bool all_matched() const {
    return sf_reader.matched_writers() >= 1 && mis_reader.matched_writers() >= 1 && dr_reader.matched_writers() >= 1 &&
           nav_reader.matched_writers() >= 1 && pong_reader.matched_writers() >= 1 &&
           ping_writer.matched_readers() >= 1;
  }
};

// Pings stamped with the steady clock at the odometer rate of a run (every 10 ms / speed; at most
// 1 kHz) from construction until stop() or destruction.
class Pinger {
 public:
  Pinger(odonav::dds::Writer<Odometer>& writer, double speed_factor)
      : thread_([this, &writer, speed_factor] {
          const double period_s = speed_factor > 0.0 ? std::max(0.01 / speed_factor, 0.001) : 0.001;
          Odometer ping;
          ping.vehicle_id("bench-ping");
          while (pinging_.load()) {
            const int64_t now = steady_ns();
            ping.header().stamp().sec(static_cast<int32_t>(now / 1000000000LL));
            ping.header().stamp().nanosec(static_cast<uint32_t>(now % 1000000000LL));
            writer.write(ping);
            std::this_thread::sleep_for(std::chrono::duration<double>(period_s));
          }
        }) {}
  ~Pinger() { stop(); }  // every path out (also an exception) stops it before its writer goes
  Pinger(const Pinger&) = delete;
  Pinger& operator=(const Pinger&) = delete;
  void stop() {
    pinging_ = false;
    if (thread_.joinable()) thread_.join();
  }

 private:
  std::atomic<bool> pinging_{true};
  std::thread thread_;
};

// Latencies of every DR output matched to its odometer sample, ns (see the file comment, (a)).
struct Latencies {
  std::vector<int64_t> end_to_end, after_last_input;
  std::vector<int64_t> end_to_end_steady, after_last_input_steady;  // outputs after the warm-up only
};

// Receive time of the last input a DR output at `stamp` needed: its odometer sample, the INS at or
// past its time, and the GNSS fix and estimates of the last epoch at or before stamp - hold-off.
int64_t release_time_ns(int64_t stamp, int64_t odometer_recv, const std::vector<Arrivals::Row>& ins_rows,
                        const std::vector<Arrivals::Row>& gnss_rows, const std::vector<Arrivals::Row>& sf_rows,
                        const std::vector<Arrivals::Row>& mis_rows, int64_t hold_off_ns) {
  int64_t release = odometer_recv;
  release = std::max(release, first_recv_at_or_after(ins_rows, stamp));
  auto g = std::upper_bound(gnss_rows.begin(), gnss_rows.end(), stamp - hold_off_ns,
                            [](int64_t v, const auto& r) { return v < r.stamp_ns; });
  if (g != gnss_rows.begin()) release = std::max(release, std::prev(g)->recv_ns);
  if (g != gnss_rows.begin()) {
    const int64_t epoch = std::prev(g)->stamp_ns;
    for (int64_t r : {first_recv_at_or_after(sf_rows, epoch), first_recv_at_or_after(mis_rows, epoch)})
      release = std::max(release, r);
  }
  return release;
}

// One run of the pipeline at one speed: the consumers and the echo, then the gateway, then the
// figures. Every child is killed on every path out (Child's destructor).
class PipelineRun {
 public:
  PipelineRun(const Setup& setup, const DatasetInfo& data, const std::string& speed)
      : setup_(setup),
        data_(data),
        real_time_(speed == "1"),
        speed_factor_(speed == "max" ? 0.0 : std::stod(speed)),
        logs_(setup.work + "/logs-" + speed) {
    result_.speed = speed;
  }

  RunResult run() {
    result_.load_before = load_average();
    mkdir(logs_.c_str(), 0755);
    shm_clean();
    odonav::dds::ParticipantOptions po;
    po.profiles_file = setup_.profile;
    po.domain_id = setup_.domain;
    po.participant_name = kProgram;
    participant_ = std::make_unique<odonav::dds::Participant>(po);
    probes_ = std::make_unique<Probes>(*participant_);
    start_consumers();
    if (const auto why = wait_until_matched()) return fail(*why);
    start_gateway();
    if (const auto why = watch_data_period()) return fail(*why);
    if (const auto why = stop_consumers()) return fail(*why);
    component_figures();
    latency_figures();
    participant_.reset();
    shm_clean();
    return result_;
  }

 private:
  std::vector<std::string> common_flags() const {
    return {"--domain",     std::to_string(setup_.domain),
            "--profile",    setup_.profile,
            "--vehicle-id", setup_.vehicle_id,
            "--log-level",  "warn"};
  }

  // Dead reckoning, identification, calibration and the echo process.
  void start_consumers() {
    // As deploy/launch: at real time an input silent 2 s is absent; faster, queues may lag more.
    std::vector<std::string> node = common_flags();
    node.insert(node.end(), {"--max-wait-s", real_time_ ? "2" : "30"});
    node.insert(node.end(), data_.component_flags.begin(), data_.component_flags.end());
    for (const std::string c : {"odonav-dead-reckoning", "odonav-identification", "odonav-calibration"}) {
      std::vector<std::string> args = node;
      if (setup_.pass_hold_off && c != "odonav-calibration")
        args.insert(args.end(), {"--estimate-hold-off-s", shortest(setup_.hold_off_s)});
      if (c == "odonav-dead-reckoning")
        args.insert(args.end(), data_.dead_reckoning_flags.begin(), data_.dead_reckoning_flags.end());
      components_.push_back(std::make_unique<Child>(c, setup_.bin_dir + "/" + c, args, logs_ + "/" + c + ".log"));
    }
    auto echo_args = common_flags();
    echo_args.insert(echo_args.begin(), "--echo");
    echo_ = std::make_unique<Child>("echo", setup_.self_path, echo_args, logs_ + "/echo.log");
  }

  // Why the consumers or the echo did not come up within 60 s; nullopt once all matched.
  std::optional<std::string> wait_until_matched() {
    const int64_t match_deadline = steady_ns() + 60000000000LL;
    while (!probes_->all_matched()) {
      for (auto& c : components_)
        if (!c->running())
          return c->name() + " exited at start with status " + std::to_string(c->exit_code()) + " (log: " + logs_ +
                 "/" + c->name() + ".log)";
      if (!echo_->running()) return "the echo process exited at start (log: " + logs_ + "/echo.log)";
      if (steady_ns() > match_deadline) return "components or echo not matched within 60 s (logs: " + logs_ + ")";
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    std::this_thread::sleep_for(
        std::chrono::seconds(1));  // their mutual matching, as the gateway waits for GNSS readers only
    return std::nullopt;
  }

  void start_gateway() {
    odo_before_ = probes_->odometer.size();
    std::vector<std::string> gw = common_flags();
    // Four GNSS readers: calibration, identification, dead reckoning and this process.
    gw.insert(gw.end(), {"--source", "replay:" + data_.dir, "--speed", result_.speed, "--wait-for-readers", "4"});
    gateway_ = std::make_unique<Child>("odonav-gateway", setup_.bin_dir + "/odonav-gateway", gw,
                                       logs_ + "/odonav-gateway.log");
    pinger_ = std::make_unique<Pinger>(probes_->ping_writer, speed_factor_);
  }

  void sample_hwm() {
    for (std::size_t i = 0; i < components_.size(); ++i)
      hwm_kb_[i] = std::max(hwm_kb_[i], proc_hwm_kb(components_[i]->pid()));
    if (!gateway_->exited()) hwm_kb_.back() = std::max(hwm_kb_.back(), proc_hwm_kb(gateway_->pid()));
  }

  // Data period: from the first odometer sample here to the gateway's exit. CPU at its start and end,
  // peak RSS sampled throughout. Why it failed, or nullopt.
  std::optional<std::string> watch_data_period() {
    const double gateway_timeout_s =
        120.0 + (speed_factor_ > 0.0 ? 1.5 * data_.duration_s / speed_factor_ : data_.duration_s);
    const int64_t start = steady_ns();
    cpu_at_start_.assign(components_.size() + 1, 0.0);
    switches_at_start_.assign(components_.size() + 1, 0);
    switches_at_end_.assign(components_.size() + 1, 0);
    hwm_kb_.assign(components_.size() + 1, 0);
    while (gateway_->running()) {
      sample_hwm();
      if (data_start_ < 0 && probes_->odometer.size() > odo_before_) {
        data_start_ = steady_ns();
        for (std::size_t i = 0; i < components_.size(); ++i) cpu_at_start_[i] = proc_cpu_s(components_[i]->pid());
        cpu_at_start_.back() = proc_cpu_s(gateway_->pid());
        for (std::size_t i = 0; i < components_.size(); ++i)
          switches_at_start_[i] = proc_context_switches(components_[i]->pid());
        switches_at_start_.back() = proc_context_switches(gateway_->pid());
      }
      // The gateway's last count before it exits (its threads' counts go with the process).
      if (data_start_ >= 0) {
        const long long n = proc_context_switches(gateway_->pid());
        if (n >= 0) switches_at_end_.back() = n;
      }
      for (auto& c : components_)
        if (!c->running()) {
          pinger_->stop();
          return c->name() + " exited early with status " + std::to_string(c->exit_code());
        }
      if (steady_ns() - start > static_cast<int64_t>(gateway_timeout_s * 1e9)) {
        pinger_->stop();
        return "odonav-gateway did not finish within " + shortest(gateway_timeout_s) + " s";
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(data_start_ < 0 ? 2 : 50));
    }
    const int64_t data_end = steady_ns();
    pinger_->stop();
    if (gateway_->exit_code() != 0 || data_start_ < 0)
      return "odonav-gateway exited with status " + std::to_string(gateway_->exit_code()) +
             (data_start_ < 0 ? " before any data arrived" : "");
    result_.data_wall_s = static_cast<double>(data_end - data_start_) * 1e-9;
    cpu_at_end_.resize(components_.size());
    for (std::size_t i = 0; i < components_.size(); ++i) {
      cpu_at_end_[i] = proc_cpu_s(components_[i]->pid());
      switches_at_end_[i] = proc_context_switches(components_[i]->pid());
    }
    sample_hwm();
    return std::nullopt;
  }

  // Lets the components drain what they hold, then stops them in data-flow order (as deploy/launch).
  std::optional<std::string> stop_consumers() {
    for (std::size_t last = 0, stable_polls = 0; stable_polls < 10;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      const std::size_t now = probes_->dead_reckoning.size();
      stable_polls = now == last ? stable_polls + 1 : 0;
      last = now;
    }
    for (const char* name : {"odonav-calibration", "odonav-identification", "odonav-dead-reckoning"})
      for (auto& c : components_)
        if (c->name() == name) {
          c->signal(SIGINT);
          if (!c->wait_exit_or_kill(std::chrono::seconds(60))) return c->name() + " did not stop within 60 s of SIGINT";
        }
    echo_->wait_exit_or_kill(std::chrono::milliseconds(0));
    std::this_thread::sleep_for(std::chrono::milliseconds(300));  // last DR outputs of finish()
    result_.load_after = load_average();
    return std::nullopt;
  }

  // Context switches per second of component i (the gateway last) over the data period; NaN if unread.
  double switches_per_s(std::size_t i, double data_s) const {
    if (switches_at_start_[i] < 0 || switches_at_end_[i] < switches_at_start_[i])
      return std::numeric_limits<double>::quiet_NaN();
    return static_cast<double>(switches_at_end_[i] - switches_at_start_[i]) / data_s;
  }

  // CPU % over the data period and peak RSS of each component.
  void component_figures() {
    const double data_s = result_.data_wall_s;
    for (std::size_t i = 0; i < components_.size(); ++i) {
      const auto& c = *components_[i];
      result_.components.push_back(ComponentFigures{c.name(), 100.0 * (cpu_at_end_[i] - cpu_at_start_[i]) / data_s,
                                                    static_cast<double>(hwm_kb_[i]) * 1024e-6,
                                                    switches_per_s(i, data_s), c.exit_code()});
    }
    // The gateway's CPU: its whole life (reaped) minus what it used before the first sample.
    result_.components.push_back(ComponentFigures{"odonav-gateway",
                                                  100.0 * (gateway_->cpu_s() - cpu_at_start_.back()) / data_s,
                                                  static_cast<double>(hwm_kb_.back()) * 1024e-6,
                                                  switches_per_s(components_.size(), data_s), gateway_->exit_code()});
    result_.samples_published = data_.odometer + data_.ins + data_.gnss;
  }

  // What arrived here on each topic, by stamp, once the components stopped.
  struct ArrivalRows {
    std::vector<Arrivals::Row> odo, ins, gnss, sf, mis, dr;
  };

  Latencies latencies(const ArrivalRows& a) const {
    Latencies l;
    const int64_t steady_from =
        a.odo.empty() ? 0 : a.odo.front().stamp_ns + static_cast<int64_t>(setup_.warmup_s * 1e9);
    for (const auto& dr : a.dr) {
      const auto it = std::lower_bound(a.odo.begin(), a.odo.end(), dr.stamp_ns,
                                       [](const auto& r, int64_t v) { return r.stamp_ns < v; });
      if (it == a.odo.end() || it->stamp_ns != dr.stamp_ns) continue;
      l.end_to_end.push_back(dr.recv_ns - it->recv_ns);
      l.after_last_input.push_back(dr.recv_ns -
                                   release_time_ns(dr.stamp_ns, it->recv_ns, a.ins, a.gnss, a.sf, a.mis,
                                                   static_cast<int64_t>(std::llround(setup_.hold_off_s * 1e9))));
      if (dr.stamp_ns >= steady_from) {
        l.end_to_end_steady.push_back(l.end_to_end.back());
        l.after_last_input_steady.push_back(l.after_last_input.back());
      }
    }
    return l;
  }

  // Latencies, the offered rate, the raw hop and the loss check.
  void latency_figures() {
    const ArrivalRows a{by_stamp(probes_->odometer.rows()),     by_stamp(probes_->ins.rows()),
                        by_stamp(probes_->gnss.rows()),         by_stamp(probes_->scale_factor.rows()),
                        by_stamp(probes_->misalignment.rows()), by_stamp(probes_->dead_reckoning.rows())};
    const Latencies l = latencies(a);
    result_.end_to_end_steady = percentiles_ms(l.end_to_end_steady);
    result_.after_last_input_steady = percentiles_ms(l.after_last_input_steady);
    // Offered rate: the samples over the span the odometer stream took to arrive here.
    if (a.odo.size() > 1) {
      const auto [first, last] = std::minmax_element(
          a.odo.begin(), a.odo.end(), [](const auto& x, const auto& y) { return x.recv_ns < y.recv_ns; });
      result_.samples_per_s = static_cast<double>(data_.odometer + data_.ins + data_.gnss) /
                              (static_cast<double>(last->recv_ns - first->recv_ns) * 1e-9);
    }
    result_.end_to_end = percentiles_ms(l.end_to_end);
    result_.after_last_input = percentiles_ms(l.after_last_input);
    // An estimate's latency after its GNSS epoch arrived here (same stamp), after the warm-up.
    auto after_gnss = [&](const std::vector<Arrivals::Row>& est) {
      std::vector<int64_t> v;
      const int64_t from = a.odo.empty() ? 0 : a.odo.front().stamp_ns + static_cast<int64_t>(setup_.warmup_s * 1e9);
      for (const auto& e : est) {
        if (e.stamp_ns < from) continue;
        const auto g = std::lower_bound(a.gnss.begin(), a.gnss.end(), e.stamp_ns,
                                        [](const auto& r, int64_t x) { return r.stamp_ns < x; });
        if (g != a.gnss.end() && g->stamp_ns == e.stamp_ns) v.push_back(e.recv_ns - g->recv_ns);
      }
      return percentiles_ms(v);
    };
    // The anchored position (rt/odonav/navigation_position) after its odometer sample, steady state.
    {
      std::vector<int64_t> v;
      const int64_t from = a.odo.empty() ? 0 : a.odo.front().stamp_ns + static_cast<int64_t>(setup_.warmup_s * 1e9);
      for (const auto& n : by_stamp(probes_->navigation.rows())) {
        if (n.stamp_ns < from) continue;
        const auto it = std::lower_bound(a.odo.begin(), a.odo.end(), n.stamp_ns,
                                         [](const auto& r, int64_t x) { return r.stamp_ns < x; });
        if (it != a.odo.end() && it->stamp_ns == n.stamp_ns) v.push_back(n.recv_ns - it->recv_ns);
      }
      result_.navigation_end_to_end_steady = percentiles_ms(v);
    }
    result_.calibration_after_gnss = after_gnss(a.mis);
    result_.identification_after_gnss = after_gnss(a.sf);
    std::vector<int64_t> hop;
    for (const auto& r : probes_->pong_rtt.rows()) hop.push_back((r.recv_ns - r.stamp_ns) / 2);
    result_.hop = percentiles_ms(hop);
    result_.dr_outputs = a.dr.size();
    result_.samples_accepted = 0;
    for (const auto& r : a.sf) result_.samples_accepted = std::max<uint64_t>(result_.samples_accepted, r.value);
    // This process's own odometer reader may miss the first sample (matched last): not a pipeline loss.
    result_.nothing_lost = result_.dr_outputs == data_.reference.dr_outputs &&
                           result_.samples_accepted == data_.reference.samples_accepted;
    result_.completed = true;
  }

  RunResult fail(const std::string& why) {
    result_.failure = why;
    for (auto& c : components_) c->wait_exit_or_kill(std::chrono::milliseconds(0));
    echo_->wait_exit_or_kill(std::chrono::milliseconds(0));
    participant_.reset();
    shm_clean();
    return result_;
  }

  const Setup& setup_;
  const DatasetInfo& data_;
  const bool real_time_;
  const double speed_factor_;
  const std::string logs_;
  RunResult result_;
  std::unique_ptr<odonav::dds::Participant> participant_;
  std::unique_ptr<Probes> probes_;
  std::vector<std::unique_ptr<Child>> components_;  // dead reckoning, identification, calibration
  std::unique_ptr<Child> echo_;
  std::unique_ptr<Child> gateway_;
  std::unique_ptr<Pinger> pinger_;  // destroyed first: it writes on probes_->ping_writer
  std::size_t odo_before_ = 0;
  int64_t data_start_ = -1;
  std::vector<double> cpu_at_start_, cpu_at_end_;               // components, then the gateway (start only)
  std::vector<long long> switches_at_start_, switches_at_end_;  // components, then the gateway
  std::vector<long> hwm_kb_;                                    // components, then the gateway
};

RunResult run_pipeline(const Setup& setup, const DatasetInfo& data, const std::string& speed) {
  return PipelineRun(setup, data, speed).run();
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
  out << "anchored position (navigation_position) after its odometer sample, steady state: "
      << format_ms(r.navigation_end_to_end_steady) << "\n";
  out << "misalignment (calibration) after its GNSS epoch arrived: " << format_ms(r.calibration_after_gnss) << "\n";
  out << "scale factor (identification) after its GNSS epoch arrived: " << format_ms(r.identification_after_gnss)
      << "\n";
  out << "raw Fast DDS hop (ping-pong / 2, same transport and QoS, same run): " << format_ms(r.hop) << "\n";
  if (r.hop.p99 > 0.0)
    out << std::setprecision(1) << "ratios (steady state): end-to-end p99 / (" << kCriticalPathHops
        << " hops x raw hop p99) = " << r.end_to_end_steady.p99 / (kCriticalPathHops * r.hop.p99)
        << "; after-last-input p99 / raw hop p99 = " << r.after_last_input_steady.p99 / r.hop.p99 << "\n";
  out << "| component | CPU % of one core (data period) | peak RSS (MB) | context switches / s | exit |\n"
         "|---|---|---|---|---|\n";
  double total_cpu = 0.0, total_no_gateway = 0.0, total_switches = 0.0;
  for (const auto& c : r.components) {
    out << "| " << c.name << " | " << std::setprecision(2) << c.cpu_percent << " | " << std::setprecision(1) << c.rss_mb
        << " | " << std::setprecision(0) << c.switches_per_s << " | " << c.exit_code << " |\n";
    total_cpu += c.cpu_percent;
    total_switches += c.switches_per_s;
    if (c.name != "odonav-gateway") total_no_gateway += c.cpu_percent;
  }
  out << "| all four | " << std::setprecision(2) << total_cpu << " | | " << std::setprecision(0) << total_switches
      << " | |\n";
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
  opts.add_double("gnss-rate", 10.0, "GNSS rate of the simulated datasets (odonav-simulator --gnss-rate), Hz", 0.1,
                  100.0);
  opts.add_double("estimate-hold-off-s", -1.0,
                  "hold-off given to dead reckoning and identification, s; < 0 = their default (0.2 s, not passed)",
                  -1.0, 10.0);
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
    setup.gnss_rate_hz = opts.get_double("gnss-rate");
    setup.pass_hold_off = opts.get_double("estimate-hold-off-s") >= 0.0;
    if (setup.pass_hold_off) setup.hold_off_s = opts.get_double("estimate-hold-off-s");
    if (setup.vehicle_id.empty()) throw odonav::ConfigError("--vehicle-id: must not be empty");
    for (const char* flag : {"speeds", "ladder"})
      for (const auto& s : split(opts.get_string(flag))) {
        if (s == "max") continue;
        char* end = nullptr;
        const double v = std::strtod(s.c_str(), &end);
        if (end == s.c_str() || *end != '\0' || !(v > 0.0))
          throw odonav::ConfigError(std::string("--") + flag + ": '" + s + "' is not a positive number or max");
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
    std::cout << "# odonav-bench-pipeline: " << std::thread::hardware_concurrency() << " cores, load " << load_average()
              << ", domain " << setup.domain << ", profile " << setup.profile << "\n";
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
                << r.data_wall_s << " s (first odometer sample -> gateway exit); DR outputs " << r.dr_outputs << " / "
                << fast.reference.dr_outputs << ", samples_accepted " << r.samples_accepted << " / "
                << fast.reference.samples_accepted << ", steady e2e " << format_ms(r.end_to_end_steady) << ", load "
                << r.load_after << ": " << (r.nothing_lost ? "nothing lost" : "LOST DATA") << "\n";
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
