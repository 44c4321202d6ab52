// SPDX-License-Identifier: MIT
// Learning-rate schedules: the base learning rate as a function of the epoch (0-based). The
// training loop calls Adam::set_lr(schedule.lr_at(epoch)) at the start of every epoch; group
// multipliers are applied by the optimiser.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

namespace g2l::nn {

/// A learning-rate schedule (immutable).
class LrSchedule {
public:
    virtual ~LrSchedule() = default;
    /// The base learning rate for 0-based `epoch`; throws if epoch < 0.
    virtual double lr_at(int64_t epoch) const = 0;
    /// A short description for logs, e.g. "step(base=0.001, every 50, gamma=0.5)".
    virtual std::string describe() const = 0;
};

/// lr = base * gamma^floor(epoch / step_epochs). The G2L-Net paper (§4.1): base 1e-3, halved
/// (gamma 0.5) every 50 epochs, 200 epochs.
class StepDecay : public LrSchedule {
public:
    /// Throws unless base >= 0 (finite), step_epochs >= 1 and gamma > 0 (finite).
    StepDecay(double base, int64_t step_epochs, double gamma);
    double lr_at(int64_t epoch) const override;
    std::string describe() const override;

private:
    double base_, gamma_;
    int64_t step_;
};

/// The released G2L-Net code: `lr /= 4` every total_epochs // 4 epochs, i.e.
/// lr = base / 4^floor(epoch / (total_epochs // 4)); 300 epochs: epochs 75..149 use base / 4.
class OfficialG2L : public LrSchedule {
public:
    /// Throws unless base >= 0 (finite) and total_epochs >= 4 (so the period is >= 1).
    OfficialG2L(double base, int64_t total_epochs);
    double lr_at(int64_t epoch) const override;
    std::string describe() const override;

private:
    double base_;
    int64_t total_, period_;
};

/// lr = base for every epoch.
class Constant : public LrSchedule {
public:
    /// Throws unless base >= 0 (finite).
    explicit Constant(double base);
    double lr_at(int64_t epoch) const override;
    std::string describe() const override;

private:
    double base_;
};

/// Builds a schedule by name (for the JSON config parsed in train/):
///   "step"     -> StepDecay(base, step, gamma)
///   "official" -> OfficialG2L(base, total)
///   "constant" -> Constant(base)
/// Arguments a kind does not use are ignored. Throws naming the kind (and the known kinds) when
/// it is unknown, or the constructor's error for bad values.
std::unique_ptr<LrSchedule> make_schedule(const std::string& kind, double base, int step,
                                          double gamma, int total);

}  // namespace g2l::nn
