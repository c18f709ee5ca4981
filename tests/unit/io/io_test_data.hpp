#pragma once
// The smallest valid dataset files of the odonav_io tests: two GNSS epochs and three odometer rows,
// each test breaking one file at a time.

namespace odonav::test {

inline const char* const kGoodGnss =
    "t,lat_deg,lon_deg,height_m,ve,vn,vu\n"
    "0.0,52.5,13.4,40.0,1.0,2.0,0.0\n"
    "1.0,52.5001,13.4001,40.5,1.5,2.5,0.1\n";
inline const char* const kGoodOdometer =
    "t,pulses,direction\n"
    "0.0,100,1\n"
    "0.5,180,1\n"
    "1.0,260,1\n";

}  // namespace odonav::test
