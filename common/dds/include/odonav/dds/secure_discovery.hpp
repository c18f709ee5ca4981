#pragma once
// What a participant with DDS Security does when it discovers another one, as policies without
// Fast DDS (docs/DDS.md §6, "The handshake race" and "Discovery floods"):
// - SetupSpacing: when the security set-up of a newly discovered participant may start, so that
//   two set-ups never run at once on two receive threads (the Fast DDS 2.9 race);
// - LogBudget: how many log lines a stream of events (participants refused, dropped) may cost.
// The DDS layer's participant listener (participant.hpp) applies both; they hold no lock and
// read no clock: the caller passes the time and serializes the calls.
#include <chrono>
#include <cstddef>
#include <cstdint>

namespace odonav::dds {

/// Spacing of the security set-ups Fast DDS 2.9 runs for newly discovered participants.
///
/// Fast DDS prepares the handshake of a discovered participant right after the discovery
/// callback returns, in the receive thread that delivered the announcement, and that preparation
/// fills temporaries shared by the whole participant without a lock. Two preparations on two
/// threads at once can leave a pair unable to authenticate. Two preparations on ONE thread cannot
/// overlap: when that thread delivers the next discovery, it has finished the previous set-up.
/// So a set-up waits only when the previous one was handed to another thread less than `spacing`
/// ago; set-ups arriving on the thread of the previous one (every announcement of a discovery
/// flood on the same socket, every participant of a UDP-only profile) never wait.
///
/// Only participants Fast DDS will prepare a handshake for go through here. One it refuses before
/// any set-up (no identity token: a participant without DDS Security) touches none of those
/// temporaries, so it neither waits nor makes a later one wait.
class SetupSpacing {
 public:
  using Clock = std::chrono::steady_clock;
  /// thread keys identify receive threads (std::hash of std::thread::id in the layer).
  using ThreadKey = std::size_t;

  explicit SetupSpacing(Clock::duration spacing) : spacing_(spacing) {}

  /// A set-up about to be handed to thread `thread` at `now`: the time it may start (`now` if it
  /// need not wait). Recorded as the latest set-up, handed over at that time on that thread.
  Clock::time_point admit(ThreadKey thread, Clock::time_point now);

  Clock::duration spacing() const { return spacing_; }
  /// Set-ups admitted, and how many of them had to wait, and for how long in total.
  std::uint64_t admitted() const { return admitted_; }
  std::uint64_t delayed() const { return delayed_; }
  Clock::duration waited() const { return waited_; }

 private:
  Clock::duration spacing_;
  bool any_ = false;
  ThreadKey last_thread_ = 0;
  Clock::time_point last_{};
  std::uint64_t admitted_ = 0;
  std::uint64_t delayed_ = 0;
  Clock::duration waited_{0};
};

/// At most `burst` log lines per `window` for one kind of event; the events beyond are counted,
/// and the next line that is granted says how many were left out before it. A flood of refused
/// participants then costs a handful of lines instead of one or two per participant.
class LogBudget {
 public:
  using Clock = std::chrono::steady_clock;
  LogBudget(std::size_t burst, Clock::duration window) : burst_(burst), window_(window) {}

  struct Grant {
    bool log = false;            ///< write this event's line
    std::uint64_t left_out = 0;  ///< events not logged since the last line written (when log)
  };
  /// One event at `now`.
  Grant take(Clock::time_point now);
  /// Events not logged since the last line written.
  std::uint64_t left_out() const { return left_out_; }

 private:
  std::size_t burst_;
  Clock::duration window_;
  bool started_ = false;
  Clock::time_point window_start_{};
  std::size_t used_ = 0;
  std::uint64_t left_out_ = 0;
};

}  // namespace odonav::dds
