#pragma once
// The estimate topics and the output files, one field table per type: which message field carries
// which row member (odonav/results/output_files.hpp), in which unit and with which "unknown"
// convention. A node publishes its component's output_row() as message_of(row) plus the fields only
// the topic has (vehicle, origin, source, ...); odonav-recorder writes row_of(message). So a field of
// both is the IDL, the row's column (visit_columns) and one line of this table.
//
// Conventions of the table (output_messages.cpp):
//   angles        radians in the row; degrees on the wire where the IDL names them _deg, written
//                 with rad_to_deg and read with exact_radians_of, so the file holds the producer's
//                 degrees unchanged
//   unknown       NaN (or nullopt) in the row; -1 on the wire (IDL "-1 = unknown"); read back, any
//                 negative or non-finite value is unknown
//   enumerations  the file's name in the row ("calibrating", "identified", "anchored"); the IDL
//                 constant on the wire
//   time          the row's t_s is the header stamp (odonav/dds/time.hpp; throws as to_time_msg)
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/NavigationPosition.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/results/output_files.hpp"

namespace odonav::dds {

/// The message of a row: every field of the table set, header frame "body" (Misalignment),
/// "odometer" (ScaleFactor), "wgs84" (DeadReckoning, NavigationPosition); the other fields default.
/// An enumeration name the IDL does not know throws std::invalid_argument naming it.
odonav::msg::Misalignment message_of(const results::MisalignmentRow& row);
odonav::msg::ScaleFactor message_of(const results::ScaleFactorRow& row);
odonav::msg::DeadReckoning message_of(const results::DeadReckoningRow& row);
odonav::msg::NavigationPosition message_of(const results::NavigationPositionRow& row);

/// The row of a message (what odonav-recorder writes). ScaleFactor: the estimator's k_<name> column
/// holds K and lambda_vff_lm_rls the forgetting factor when the estimator is vff_lm_rls and K has a
/// value; epoch_status is not on the wire (empty). An enumeration value the IDL does not know reads
/// as the first name (a newer peer's value is kept out of the file rather than crashing it).
results::MisalignmentRow row_of(const odonav::msg::Misalignment& message);
results::ScaleFactorRow row_of(const odonav::msg::ScaleFactor& message);
results::DeadReckoningRow row_of(const odonav::msg::DeadReckoning& message);
results::NavigationPositionRow row_of(const odonav::msg::NavigationPosition& message);

}  // namespace odonav::dds
