#pragma once
// SIGINT and SIGTERM as a request to stop: the test tools (the discovery flood, the multi-host
// intruder) leave their loops, print what they counted and exit normally.
#include <signal.h>

#include <atomic>

namespace odonav::test {

/// Set once SIGINT or SIGTERM arrived after stop_on_signals(); the tools may set it themselves.
inline std::atomic<bool> g_stop{false};

/// Makes SIGINT and SIGTERM set g_stop instead of ending the process.
inline void stop_on_signals() {
  struct sigaction sa {};
  sa.sa_handler = [](int) { g_stop.store(true); };
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

}  // namespace odonav::test
