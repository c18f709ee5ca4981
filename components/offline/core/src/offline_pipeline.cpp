#include "odonav/offline/offline_pipeline.hpp"

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "odonav/stream_buffers.hpp"
#include "odonav/wire_time.hpp"

namespace odonav::offline {
namespace {
// The aligners' wall clock: constant, so no input is ever declared absent (the dataset holds every
// sample; a silent stream is one that has no data, and the watermark rules cover it).
constexpr double kNow_s = 0.0;
// Any positive maximum wait: with a constant clock it never expires.
constexpr double kMaxWait_s = 1.0;
}  // namespace

/// A consumer component's aligner over the inputs its core declares (the list its DDS node
/// subscribes), but an estimate stream no component of this run produces (no identification: no
/// scale_factor to wait for).
struct OfflinePipeline::Consumer {
  using StreamId = EventTimeAligner::StreamId;
  EventTimeAligner aligner{kMaxWait_s, kNow_s};
  std::optional<StreamId> odometer, gnss, ins, misalignment, scale_factor;

  Consumer(const std::vector<ComponentInput>& inputs, bool scale_factor_produced) {
    for (const ComponentInput& in : inputs) {
      if (in.name == "scale_factor" && !scale_factor_produced) continue;
      std::optional<StreamId>& slot = stream(in.name);
      slot = in.paced_by.empty() ? aligner.add_stream(in.name, in.hold_off_s)
                                 : aligner.add_paced_stream(in.name, *stream(in.paced_by), in.hold_off_s);
    }
  }
  std::optional<StreamId>& stream(const std::string& name) {
    if (name == "odometer") return odometer;
    if (name == "gnss") return gnss;
    if (name == "ins") return ins;
    if (name == "misalignment") return misalignment;
    if (name == "scale_factor") return scale_factor;
    throw std::logic_error("offline pipeline: no stream '" + name + "' on the in-process bus");
  }
  /// Whether a sample of `input` reaches the component: it has the input and the aligner admits it.
  bool admit(const std::optional<StreamId>& input, double t_s) {
    return input && aligner.on_sample(*input, t_s, kNow_s) == SampleAdmission::kAccepted;
  }
  /// Whether a sample of stream `input` stamped t_s reaches the component whose inputs are c: the
  /// component runs (c is not null: its core exists too) and admits it.
  static bool admits(Consumer* c, std::optional<StreamId> Consumer::*input, double t_s) {
    return c && c->admit(c->*input, t_s);
  }
};

OfflinePipeline::OfflinePipeline(const PipelineConfig& config, PipelineSink& sink)
    : config_(config), sink_(sink), calibration_(config.calibration) {
  if (config_.identification) {
    identification_ = std::make_unique<identification::IdentificationCore>(*config_.identification);
    identification_inputs_ =
        std::make_unique<Consumer>(identification::identification_inputs(*config_.identification), false);
  }
  if (config_.dead_reckoning) {
    dead_reckoning_ = std::make_unique<dead_reckoning::DeadReckoningComponent>(*config_.dead_reckoning,
                                                                               config_.anchored, config_.navigation);
    dead_reckoning_inputs_ = std::make_unique<Consumer>(dead_reckoning::dead_reckoning_inputs(*config_.dead_reckoning),
                                                        identification_ != nullptr);
  }
}

OfflinePipeline::~OfflinePipeline() = default;

void OfflinePipeline::advance_to(double t_s) {
  if (finished_) throw StreamInputError("offline pipeline: sample after the end of data");
  if (pending_t_s_ && t_s < *pending_t_s_)
    throw StreamInputError("offline pipeline: samples not in time order across the inputs");
  // Every sample stamped <= the pending stamp has been passed: process up to it.
  if (pending_t_s_ && t_s > *pending_t_s_) process(*pending_t_s_);
  pending_t_s_ = t_s;
}

template <class Sample>
Sample OfflinePipeline::arrive(const Sample& sample) {
  Sample s = sample;
  try {
    s.t_s = wire_time_s(sample.t_s);
  } catch (const std::invalid_argument& e) {
    throw StreamInputError(std::string("offline pipeline: sample stamp: ") + e.what());
  }
  advance_to(s.t_s);
  return s;
}

void OfflinePipeline::add_odometer(const OdometerSample& sample) {
  const OdometerSample s = arrive(sample);
  if (Consumer::admits(identification_inputs_.get(), &Consumer::odometer, s.t_s)) identification_->add_odometer(s);
  if (Consumer::admits(dead_reckoning_inputs_.get(), &Consumer::odometer, s.t_s)) dead_reckoning_->add_odometer(s);
}

void OfflinePipeline::add_gnss(const GnssSample& sample) {
  const GnssSample s = arrive(sample);
  last_gnss_t_s_ = s.t_s;
  calibration_.add_gnss(s);
  if (Consumer::admits(identification_inputs_.get(), &Consumer::gnss, s.t_s)) identification_->add_gnss(s);
  if (Consumer::admits(dead_reckoning_inputs_.get(), &Consumer::gnss, s.t_s)) dead_reckoning_->add_gnss(s);
}

void OfflinePipeline::add_ins(const InsSample& sample) {
  const InsSample s = arrive(sample);
  if (config_.calibration.use_ins) calibration_.add_ins(s);
  if (Consumer::admits(identification_inputs_.get(), &Consumer::ins, s.t_s)) identification_->add_ins(s);
  if (Consumer::admits(dead_reckoning_inputs_.get(), &Consumer::ins, s.t_s)) dead_reckoning_->add_ins(s);
}

void OfflinePipeline::process(double complete_through_s) {
  // What the gateway declares on each sensor sample: GNSS is complete up to here.
  for (Consumer* in : {identification_inputs_.get(), dead_reckoning_inputs_.get()})
    if (in && in->gnss) in->aligner.declare_published(*in->gnss, complete_through_s, last_gnss_t_s_);
  deliver_misalignments(calibration_.process_until(complete_through_s));
  if (identification_)
    if (const auto w = identification_inputs_->aligner.advance(kNow_s))
      deliver_scale_factors(identification_->process_until(*w));
  if (dead_reckoning_)
    if (const auto w = dead_reckoning_inputs_->aligner.advance(kNow_s))
      deliver_dead_reckoning(dead_reckoning_->process_until(*w));
}

void OfflinePipeline::finish() {
  if (finished_) return;
  if (pending_t_s_) process(*pending_t_s_);
  finished_ = true;
  // In pipeline order, as the nodes drain: each consumer has every estimate before it finishes.
  deliver_misalignments(calibration_.finish());
  if (identification_) deliver_scale_factors(identification_->finish());
  if (dead_reckoning_) deliver_dead_reckoning(dead_reckoning_->finish());
}

void OfflinePipeline::deliver_misalignments(const std::vector<calibration::MisalignmentOutput>& outputs) {
  for (const calibration::MisalignmentOutput& m : outputs) {
    sink_.on_misalignment(m);
    const PublishedMisalignment p = calibration::published_misalignment(m);
    if (Consumer::admits(identification_inputs_.get(), &Consumer::misalignment, p.t_s))
      identification_->apply_misalignment(p);
    if (Consumer::admits(dead_reckoning_inputs_.get(), &Consumer::misalignment, p.t_s))
      dead_reckoning_->on_misalignment(p);
  }
}

void OfflinePipeline::deliver_scale_factors(const std::vector<identification::IdentificationOutput>& outputs) {
  for (const identification::IdentificationOutput& k : outputs) {
    sink_.on_scale_factor(k);
    if (Consumer::admits(dead_reckoning_inputs_.get(), &Consumer::scale_factor, k.t_s))
      dead_reckoning_->on_scale_factor(identification::published_scale_factor(k, config_.identification_source),
                                       kNow_s);
  }
}

void OfflinePipeline::deliver_dead_reckoning(std::vector<dead_reckoning::DeadReckoningOutput> outputs) {
  for (dead_reckoning::DeadReckoningOutput& o : outputs)
    sink_.on_dead_reckoning(dead_reckoning_->publish(std::move(o)));
}

}  // namespace odonav::offline
