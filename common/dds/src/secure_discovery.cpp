// Policies of a secure participant towards the participants it discovers (secure_discovery.hpp).
#include "odonav/dds/secure_discovery.hpp"

#include <algorithm>

namespace odonav::dds {

SetupSpacing::Clock::time_point SetupSpacing::admit(ThreadKey thread, Clock::time_point now) {
  Clock::time_point start = now;
  // The previous set-up runs on its own thread right after it was handed over: only a set-up on
  // another thread can overlap it.
  if (any_ && thread != last_thread_) start = std::max(now, last_ + spacing_);
  ++admitted_;
  if (start > now) {
    ++delayed_;
    waited_ += start - now;
  }
  any_ = true;
  last_thread_ = thread;
  last_ = start;
  return start;
}

LogBudget::Grant LogBudget::take(Clock::time_point now) {
  if (!started_ || now - window_start_ >= window_) {
    started_ = true;
    window_start_ = now;
    used_ = 0;
  }
  if (used_ >= burst_) {
    ++left_out_;
    return {};
  }
  ++used_;
  Grant g{true, left_out_};
  left_out_ = 0;
  return g;
}

}  // namespace odonav::dds
