#pragma once
// Which recording a folder of results was computed from, so that results are never scored against
// another drive's data. odonav-offline and the recorder write it (run.json in the output folder);
// odonav-evaluate and odonav-report check it before they compute anything.
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "odonav/dataset.hpp"

namespace odonav {

/// File name of the provenance record inside an output folder.
inline constexpr const char* kProvenanceFile = "run.json";

struct RunProvenance {
  std::string tool;  ///< "odonav-offline", "odonav-recorder".
  /// The dataset's meta.json vehicle_id (compared with the dataset's); empty when the writer did not
  /// read the dataset.
  std::string vehicle_id;
  /// The pipeline's --vehicle-id (the DDS key), when a recorder wrote the folder: informational, it
  /// need not equal the dataset's vehicle_id (a replay may run under any id).
  std::string dds_vehicle_id;
  /// dataset_fingerprint() of the dataset, when the writer read it (odonav-offline); empty otherwise.
  std::string dataset_fingerprint;
  /// Event-time span of the data the run saw (s, the dataset's time base); NaN when unknown.
  double t_first_s = std::numeric_limits<double>::quiet_NaN();
  double t_last_s = std::numeric_limits<double>::quiet_NaN();
};

/// A 16-hex-digit digest of the dataset's content (every GNSS epoch's time and position, every
/// odometer sample's time and count, the vehicle id): equal for the same recording read twice,
/// different for another drive even with the same vehicle id and time span.
std::string dataset_fingerprint(const Dataset& dataset);

/// dataset_fingerprint computed as the samples pass, for a dataset read as a stream: the digest runs
/// over the vehicle id, then every GNSS sample, then every odometer sample, in file order, so every
/// GNSS sample must be added before the first odometer sample (std::logic_error otherwise).
class DatasetFingerprint {
 public:
  explicit DatasetFingerprint(const std::string& vehicle_id);
  void add(const GnssSample& gnss);
  void add(const OdometerSample& odometer);
  /// 16 hex digits, as dataset_fingerprint.
  std::string text() const;

 private:
  uint64_t h_;
  bool odometer_started_ = false;
};

/// The provenance of `dataset` as odonav-offline records it.
RunProvenance provenance_of(const Dataset& dataset, const std::string& tool);

/// JSON text of `p` (one object; NaN times as null).
std::string provenance_json(const RunProvenance& p);
/// Reads `<folder>/run.json`; nullopt when the file is absent. Throws std::runtime_error naming the
/// file when it exists but is not a provenance record.
std::optional<RunProvenance> read_provenance(const std::string& folder);

/// Every reason the results of `results` (its provenance, and the event-time span [t_first_s,
/// t_last_s] of its rows) cannot belong to `dataset`: another vehicle, another recording, or rows
/// outside the dataset's time span by more than tolerance_s. Empty when they may belong.
std::vector<std::string> provenance_mismatches(const std::optional<RunProvenance>& results, double rows_t_first_s,
                                               double rows_t_last_s, const Dataset& dataset, double tolerance_s = 1.0);

}  // namespace odonav
