// SPDX-License-Identifier: MIT
#include "nn/schedule.h"

#include <cmath>

#include "core/error.h"

namespace g2l::nn {

namespace {

void check_base(const char* who, double base) {
    G2L_CHECK(std::isfinite(base) && base >= 0, who, ": base learning rate must be finite and >= 0,"
              " got ", base);
}

void check_epoch(const char* who, int64_t epoch) {
    G2L_CHECK(epoch >= 0, who, "::lr_at: epoch must be >= 0, got ", epoch);
}

}  // namespace

StepDecay::StepDecay(double base, int64_t step_epochs, double gamma)
    : base_(base), gamma_(gamma), step_(step_epochs) {
    check_base("StepDecay", base);
    G2L_CHECK(step_epochs >= 1, "StepDecay: step_epochs must be >= 1, got ", step_epochs);
    G2L_CHECK(std::isfinite(gamma) && gamma > 0, "StepDecay: gamma must be finite and > 0, got ",
              gamma);
}

double StepDecay::lr_at(int64_t epoch) const {
    check_epoch("StepDecay", epoch);
    // Repeated multiplication (not pow) so the values equal what an "lr *= gamma" loop gives.
    double lr = base_;
    for (int64_t k = epoch / step_; k > 0; --k) lr *= gamma_;
    return lr;
}

std::string StepDecay::describe() const {
    return cat("step(base=", base_, ", every ", step_, " epochs, gamma=", gamma_, ")");
}

OfficialG2L::OfficialG2L(double base, int64_t total_epochs)
    : base_(base), total_(total_epochs), period_(total_epochs / 4) {
    check_base("OfficialG2L", base);
    G2L_CHECK(total_epochs >= 4, "OfficialG2L: total_epochs must be >= 4 (lr /= 4 every "
              "total_epochs // 4 epochs), got ", total_epochs);
}

double OfficialG2L::lr_at(int64_t epoch) const {
    check_epoch("OfficialG2L", epoch);
    double lr = base_;
    for (int64_t k = epoch / period_; k > 0; --k) lr /= 4.0;
    return lr;
}

std::string OfficialG2L::describe() const {
    return cat("official(base=", base_, ", lr /= 4 every ", period_, " of ", total_, " epochs)");
}

Constant::Constant(double base) : base_(base) { check_base("Constant", base); }

double Constant::lr_at(int64_t epoch) const {
    check_epoch("Constant", epoch);
    return base_;
}

std::string Constant::describe() const { return cat("constant(base=", base_, ")"); }

std::unique_ptr<LrSchedule> make_schedule(const std::string& kind, double base, int step,
                                          double gamma, int total) {
    if (kind == "step") return std::make_unique<StepDecay>(base, step, gamma);
    if (kind == "official") return std::make_unique<OfficialG2L>(base, total);
    if (kind == "constant") return std::make_unique<Constant>(base);
    G2L_CHECK(false, "make_schedule: unknown schedule kind '", kind,
              "' (known: step, official, constant)");
    return nullptr;
}

}  // namespace g2l::nn
