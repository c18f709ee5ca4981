#include "offline_pipeline.hpp"

#include <utility>

#include "odonav/stream_buffers.hpp"

namespace odonav::offline {
namespace {
// The aligners' wall clock: constant, so no input is ever declared absent (the dataset holds every
// sample; a silent stream is one that has no data, and the watermark rules cover it).
constexpr double kNow_s = 0.0;
// Any positive maximum wait: with a constant clock it never expires.
constexpr double kMaxWait_s = 1.0;
}  // namespace

/// A consumer component's inputs, declared as its DDS node declares them (the node's add_input calls).
struct OfflinePipeline::Consumer {
  EventTimeAligner aligner{kMaxWait_s, kNow_s};
  EventTimeAligner::StreamId odometer = 0;
  EventTimeAligner::StreamId gnss = 0;
  std::optional<EventTimeAligner::StreamId> ins;
  EventTimeAligner::StreamId misalignment = 0;
  std::optional<EventTimeAligner::StreamId> scale_factor;

  bool admit(EventTimeAligner::StreamId stream, double t_s) {
    return aligner.on_sample(stream, t_s, kNow_s) == SampleAdmission::kAccepted;
  }
};

OfflinePipeline::OfflinePipeline(const PipelineConfig& config, PipelineSink& sink)
    : config_(config), sink_(sink), calibration_(config.calibration) {
  if (config_.identification) {
    const IdentificationParams& p = *config_.identification;
    identification_ = std::make_unique<IdentificationCore>(p);
    // As IdentificationNode: odometer, GNSS, misalignment paced by GNSS with the hold-off, INS.
    auto in = std::make_unique<Consumer>();
    in->odometer = in->aligner.add_stream("odometer");
    in->gnss = in->aligner.add_stream("gnss");
    in->misalignment = in->aligner.add_paced_stream("misalignment", in->gnss, p.estimate_hold_off_s);
    if (p.builder.use_ins) in->ins = in->aligner.add_stream("ins");
    identification_inputs_ = std::move(in);
  }
  if (config_.dead_reckoning) {
    const DeadReckonerParams& p = *config_.dead_reckoning;
    dead_reckoning_ = std::make_unique<DeadReckoningComponent>(p, config_.anchored, config_.navigation);
    // As DeadReckoningNode: odometer; GNSS with the hold-off; misalignment and scale factor paced by
    // GNSS with the hold-off; INS.
    auto in = std::make_unique<Consumer>();
    in->odometer = in->aligner.add_stream("odometer");
    in->gnss = in->aligner.add_stream("gnss", p.estimate_hold_off_s);
    in->misalignment = in->aligner.add_paced_stream("misalignment", in->gnss, p.estimate_hold_off_s);
    if (identification_) in->scale_factor = in->aligner.add_paced_stream("scale_factor", in->gnss, p.estimate_hold_off_s);
    if (p.use_ins) in->ins = in->aligner.add_stream("ins");
    dead_reckoning_inputs_ = std::move(in);
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

void OfflinePipeline::add_odometer(const OdometerSample& s) {
  advance_to(s.t_s);
  if (identification_ && identification_inputs_->admit(identification_inputs_->odometer, s.t_s))
    identification_->add_odometer(s);
  if (dead_reckoning_ && dead_reckoning_inputs_->admit(dead_reckoning_inputs_->odometer, s.t_s))
    dead_reckoning_->add_odometer(s);
}

void OfflinePipeline::add_gnss(const GnssSample& s) {
  advance_to(s.t_s);
  last_gnss_t_s_ = s.t_s;
  calibration_.add_gnss(s);
  if (identification_ && identification_inputs_->admit(identification_inputs_->gnss, s.t_s))
    identification_->add_gnss(s);
  if (dead_reckoning_ && dead_reckoning_inputs_->admit(dead_reckoning_inputs_->gnss, s.t_s))
    dead_reckoning_->add_gnss(s);
}

void OfflinePipeline::add_ins(const InsSample& s) {
  advance_to(s.t_s);
  if (config_.calibration.use_ins) calibration_.add_ins(s);
  if (identification_ && identification_inputs_->ins &&
      identification_inputs_->admit(*identification_inputs_->ins, s.t_s))
    identification_->add_ins(s);
  if (dead_reckoning_ && dead_reckoning_inputs_->ins && dead_reckoning_inputs_->admit(*dead_reckoning_inputs_->ins, s.t_s))
    dead_reckoning_->add_ins(s);
}

void OfflinePipeline::process(double complete_through_s) {
  // What the gateway declares on each sensor sample: GNSS is complete up to here.
  for (Consumer* in : {identification_inputs_.get(), dead_reckoning_inputs_.get()})
    if (in) in->aligner.declare_published(in->gnss, complete_through_s, last_gnss_t_s_);
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

void OfflinePipeline::deliver_misalignments(std::vector<MisalignmentOutput> outputs) {
  for (const MisalignmentOutput& m : outputs) {
    sink_.on_misalignment(m);
    const PublishedMisalignment p = published_misalignment(m);
    if (identification_ && identification_inputs_->admit(identification_inputs_->misalignment, p.t_s))
      identification_->apply_misalignment(p);
    if (dead_reckoning_ && dead_reckoning_inputs_->admit(dead_reckoning_inputs_->misalignment, p.t_s))
      dead_reckoning_->on_misalignment(p);
  }
}

void OfflinePipeline::deliver_scale_factors(std::vector<IdentificationOutput> outputs) {
  for (const IdentificationOutput& k : outputs) {
    sink_.on_scale_factor(k);
    if (dead_reckoning_ && dead_reckoning_inputs_->admit(*dead_reckoning_inputs_->scale_factor, k.t_s))
      dead_reckoning_->on_scale_factor(published_scale_factor(k, config_.identification_source), kNow_s);
  }
}

void OfflinePipeline::deliver_dead_reckoning(std::vector<DeadReckoningOutput> outputs) {
  for (DeadReckoningOutput& o : outputs) sink_.on_dead_reckoning(dead_reckoning_->publish(std::move(o)));
}

}  // namespace odonav::offline
