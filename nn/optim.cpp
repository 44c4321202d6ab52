// SPDX-License-Identifier: MIT
#include "nn/optim.h"

#include <cmath>
#include <set>
#include <sstream>

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/adam.h"

namespace g2l::nn {

namespace {

// Key prefixes of the optimiser state inside a training checkpoint, which also holds the
// model's tensors; load_state only judges keys under "adam.".
const std::string kM = "adam.m.", kV = "adam.v.", kStep = "adam.step.";

void check_hyper(const AdamOptions& o) {
    G2L_CHECK(std::isfinite(o.lr) && o.lr >= 0, "Adam: lr must be finite and >= 0, got ", o.lr);
    G2L_CHECK(o.beta1 >= 0 && o.beta1 < 1, "Adam: beta1 must be in [0, 1), got ", o.beta1);
    G2L_CHECK(o.beta2 >= 0 && o.beta2 < 1, "Adam: beta2 must be in [0, 1), got ", o.beta2);
    G2L_CHECK(std::isfinite(o.eps) && o.eps >= 0, "Adam: eps must be finite and >= 0, got ",
              o.eps);
}

void check_param(const ParamGroup& g, const std::string& name, const Tensor& p) {
    const std::string where = cat("Adam: parameter '", name, "' of group '", g.name, "'");
    G2L_CHECK(!name.empty(), "Adam: empty parameter name in group '", g.name, "'");
    G2L_CHECK(p.defined(), where, " is undefined");
    G2L_CHECK(p.is_leaf(), where, " is not a leaf (it was produced by an op): ", p.desc());
    G2L_CHECK(p.dtype() == DType::F32 || p.dtype() == DType::F64, where,
              " must be f32 or f64, got ", p.desc());
    G2L_CHECK(p.requires_grad(), where, " does not require grad: ", p.desc());
    G2L_CHECK(p.device().is_cpu(), where, " must be on the cpu (no CUDA Adam yet), got ",
              p.desc());
}

}  // namespace

Adam::Adam(std::vector<ParamGroup> groups, AdamOptions options)
    : groups_(std::move(groups)), opt_(options) {
    check_hyper(opt_);
    G2L_CHECK(!groups_.empty(), "Adam: no parameter groups given");
    std::set<std::string> names;
    std::vector<std::pair<std::string, Tensor>> seen;
    for (const ParamGroup& g : groups_) {
        G2L_CHECK(!g.params.empty(), "Adam: group '", g.name, "' has no parameters");
        G2L_CHECK(std::isfinite(g.lr_mult) && g.lr_mult >= 0, "Adam: group '", g.name,
                  "': lr_mult must be finite and >= 0, got ", g.lr_mult);
        G2L_CHECK(std::isfinite(g.weight_decay) && g.weight_decay >= 0, "Adam: group '", g.name,
                  "': weight_decay must be finite and >= 0, got ", g.weight_decay);
        std::vector<Slot> slots;
        for (const auto& [name, p] : g.params) {
            check_param(g, name, p);
            G2L_CHECK(names.insert(name).second, "Adam: duplicate parameter name '", name,
                      "' (group '", g.name, "')");
            // The same tensor listed twice would be stepped twice per step, with two moment sets.
            for (const auto& [other, q] : seen) {
                G2L_CHECK(!p.shares_storage_with(q), "Adam: parameters '", other, "' and '",
                          name, "' share storage (the same tensor listed twice)");
            }
            seen.emplace_back(name, p);
            // m and v start at zero; the bias corrections in step() undo that start-up bias.
            slots.push_back({Tensor::zeros(p.shape(), p.dtype(), p.device()),
                             Tensor::zeros(p.shape(), p.dtype(), p.device()), 0});
        }
        slots_.push_back(std::move(slots));
    }
}

void Adam::step() {
    // The in-place parameter updates must not be recorded into any graph.
    autograd::NoGradGuard no_grad;
    for (size_t gi = 0; gi < groups_.size(); ++gi) {
        const ParamGroup& group = groups_[gi];
        for (size_t pi = 0; pi < group.params.size(); ++pi) {
            const auto& [name, param] = group.params[pi];
            const Tensor grad = param.grad();
            if (!grad.defined()) continue;  // PyTorch: params without a grad are skipped
            G2L_CHECK(grad.shape() == param.shape() && grad.dtype() == param.dtype() &&
                          grad.device() == param.device(),
                      "Adam::step: gradient ", grad.desc(), " of parameter '", name,
                      "' does not match the parameter ", param.desc());
            Slot& s = slots_[gi][pi];
            // Steps are counted per parameter (as PyTorch's state['step']): a parameter skipped
            // for lack of a gradient keeps its own bias-correction count.
            ++s.t;
            kernels::AdamArgs a;
            // Per-group multipliers: the released G2L script trains each sub-network at its own
            // rate (spec §6: seg x1, T-net x10, EVF x1, R_res x20, Rotation_pre x30); set_lr sets
            // only the base.
            a.lr = opt_.lr * group.lr_mult;
            a.beta1 = opt_.beta1;
            a.beta2 = opt_.beta2;
            a.eps = opt_.eps;
            a.weight_decay = group.weight_decay;
            // Bias corrections 1 - beta^t in double on the host (Adam, Kingma & Ba 2015, Alg. 1).
            a.bias_corr1 = 1.0 - std::pow(opt_.beta1, double(s.t));
            a.bias_corr2 = 1.0 - std::pow(opt_.beta2, double(s.t));
            a.decoupled = opt_.decoupled;
            Tensor p = param;  // handle: writes go to the caller's storage
            kernels::adam_update(p, grad, s.m, s.v, a);
        }
    }
    ++step_count_;
}

void Adam::zero_grad() {
    for (ParamGroup& g : groups_) {
        for (auto& np : g.params) np.second.zero_grad();
    }
}

void Adam::set_lr(double base_lr) {
    G2L_CHECK(std::isfinite(base_lr) && base_lr >= 0,
              "Adam::set_lr: learning rate must be finite and >= 0, got ", base_lr);
    opt_.lr = base_lr;
}

std::vector<std::pair<std::string, Tensor>> Adam::state_tensors() const {
    std::vector<std::pair<std::string, Tensor>> out;
    for (size_t gi = 0; gi < groups_.size(); ++gi) {
        for (size_t pi = 0; pi < groups_[gi].params.size(); ++pi) {
            const std::string& name = groups_[gi].params[pi].first;
            const Slot& s = slots_[gi][pi];
            // Clones: the caller may hold the snapshot while later steps keep updating m and v.
            out.emplace_back(kM + name, s.m.clone());
            out.emplace_back(kV + name, s.v.clone());
            // Stored as an i32 tensor: checkpoints hold tensors of f32, f64 or i32 only.
            out.emplace_back(kStep + name, Tensor::from_vector<int32_t>({int32_t(s.t)}, {1}));
        }
    }
    return out;
}

void Adam::load_state(const std::map<std::string, Tensor>& state, int64_t step) {
    // Collect every mismatch and throw once, so one failed resume lists all that is wrong.
    std::ostringstream problems;
    int n_problems = 0;
    auto problem = [&](const std::string& text) {
        problems << "\n  " << text;
        ++n_problems;
    };
    std::set<std::string> expected;
    auto check = [&](const std::string& key, const Shape& shape, DType dt) {
        expected.insert(key);
        const auto it = state.find(key);
        if (it == state.end()) return problem(cat("missing '", key, "'"));
        const Tensor& t = it->second;
        if (!t.defined()) return problem(cat("'", key, "' is undefined"));
        if (t.shape() != shape || t.dtype() != dt) {
            problem(cat("'", key, "' is ", t.desc(), ", expected ", dtype_name(dt),
                        shape_str(shape)));
        }
    };
    for (size_t gi = 0; gi < groups_.size(); ++gi) {
        for (const auto& [name, p] : groups_[gi].params) {
            check(kM + name, p.shape(), p.dtype());
            check(kV + name, p.shape(), p.dtype());
            check(kStep + name, {1}, DType::I32);
        }
    }
    for (const auto& kv : state) {
        // Keys outside "adam." belong to the rest of the checkpoint (model weights): ignored.
        if (kv.first.rfind("adam.", 0) == 0 && !expected.count(kv.first)) {
            problem(cat("'", kv.first, "' matches no parameter of this optimiser"));
        }
    }
    if (step < 0) problem(cat("global step must be >= 0, got ", step));
    // Only when every key is present with the right shape and dtype: state.at() and item() would
    // throw or misread otherwise.
    for (size_t gi = 0; gi < groups_.size() && n_problems == 0; ++gi) {
        for (const auto& [name, p] : groups_[gi].params) {
            const int32_t t = state.at(kStep + name).item<int32_t>();
            if (t < 0) problem(cat("'", kStep, name, "' is negative: ", t));
        }
    }
    G2L_CHECK(n_problems == 0, "Adam::load_state: ", n_problems, " problem(s):", problems.str());
    // Nothing is written until all checks passed, so a failed load leaves the optimiser as it was.
    for (size_t gi = 0; gi < groups_.size(); ++gi) {
        for (size_t pi = 0; pi < groups_[gi].params.size(); ++pi) {
            const std::string& name = groups_[gi].params[pi].first;
            Slot& s = slots_[gi][pi];
            s.m.copy_(state.at(kM + name));
            s.v.copy_(state.at(kV + name));
            s.t = state.at(kStep + name).item<int32_t>();
        }
    }
    step_count_ = step;
}

}  // namespace g2l::nn
