#pragma once
// The DDS layer's name for odonav/silence_tracker.hpp (the middleware-free edge detection).
#include "odonav/silence_tracker.hpp"
