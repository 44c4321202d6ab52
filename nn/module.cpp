// SPDX-License-Identifier: MIT
#include "nn/module.h"

#include <cmath>

#include "core/autograd.h"

namespace g2l::nn {

void Module::check_new_name(const std::string& name) const {
    // Dots separate the levels of state_dict keys ("seg.conv1.weight"), so a dotted member name
    // would make keys ambiguous.
    G2L_CHECK(!name.empty() && name.find('.') == std::string::npos,
              "Module: bad member name '", name, "' (non-empty, no dots)");
    // Parameters, buffers and children share one key space in state_dict.
    for (const auto& p : params_) G2L_CHECK(p.first != name, "Module: duplicate name '", name, "'");
    for (const auto& p : buffers_) G2L_CHECK(p.first != name, "Module: duplicate name '", name, "'");
    for (const auto& p : children_) G2L_CHECK(p.first != name, "Module: duplicate name '", name, "'");
}

Tensor Module::register_parameter(const std::string& name, Tensor t) {
    check_new_name(name);
    G2L_CHECK(t.defined(), "Module: parameter '", name, "' is undefined");
    t.set_requires_grad(true);
    params_.emplace_back(name, t);
    return t;
}

Tensor Module::register_buffer(const std::string& name, Tensor t) {
    check_new_name(name);
    G2L_CHECK(t.defined(), "Module: buffer '", name, "' is undefined");
    buffers_.emplace_back(name, t);
    return t;
}

void Module::add_child(const std::string& name, std::shared_ptr<Module> m) {
    check_new_name(name);
    G2L_CHECK(m != nullptr, "Module: child '", name, "' is null");
    children_.emplace_back(name, std::move(m));
}

void Module::collect(const std::string& prefix, bool params, NamedTensors& out) const {
    // Vectors, not maps: names come out in registration order, the same on every run.
    for (const auto& [n, t] : params ? params_ : buffers_) out.emplace_back(prefix + n, t);
    for (const auto& [n, c] : children_) c->collect(prefix + n + ".", params, out);
}

NamedTensors Module::named_parameters() const {
    NamedTensors out;
    collect("", true, out);
    return out;
}

NamedTensors Module::named_buffers() const {
    NamedTensors out;
    collect("", false, out);
    return out;
}

std::vector<Tensor> Module::parameters() const {
    std::vector<Tensor> out;
    for (auto& p : named_parameters()) out.push_back(p.second);
    return out;
}

std::map<std::string, Tensor> Module::state_dict() const {
    std::map<std::string, Tensor> sd;
    for (auto& p : named_parameters()) sd.emplace(p.first, p.second);
    // Buffers (BatchNorm running statistics) are not trained but eval mode needs them.
    for (auto& p : named_buffers()) sd.emplace(p.first, p.second);
    return sd;
}

void Module::load_state_dict(const std::map<std::string, Tensor>& sd, bool strict) {
    std::map<std::string, Tensor> mine = state_dict();
    std::string missing, unexpected, mismatched;
    for (const auto& [name, t] : mine) {
        auto it = sd.find(name);
        if (it == sd.end()) { missing += " " + name; continue; }
        if (it->second.shape() != t.shape() || it->second.dtype() != t.dtype())
            mismatched += cat(" ", name, " (model ", t.desc(), ", given ", it->second.desc(), ")");
    }
    for (const auto& [name, t] : sd)
        if (!mine.count(name)) unexpected += " " + name;
    // A wrong shape or dtype is always an error; only missing/unexpected keys are tolerated, and
    // only when !strict (partial loads).
    G2L_CHECK(mismatched.empty() && (!strict || (missing.empty() && unexpected.empty())),
              "load_state_dict:", missing.empty() ? "" : " missing:" + missing,
              unexpected.empty() ? "" : " unexpected:" + unexpected,
              mismatched.empty() ? "" : " shape/dtype mismatch:" + mismatched);
    // Checked in full above, so the copy below is all-or-nothing.
    autograd::NoGradGuard no_grad;
    for (auto& [name, t] : mine) {
        auto it = sd.find(name);
        // copy_ into the existing storage instead of swapping handles: the optimiser and any other
        // holder of the parameter see the loaded values.
        if (it != sd.end()) t.copy_(it->second);
    }
}

void Module::train(bool on) {
    training_ = on;
    for (auto& c : children_) c.second->train(on);
}

int64_t Module::num_parameters() const {
    int64_t n = 0;
    for (auto& p : named_parameters()) n += p.second.numel();
    return n;
}

void Module::zero_grad() {
    for (auto& p : named_parameters()) p.second.zero_grad();
}

Tensor uniform_init(const Shape& shape, int64_t fan_in, Rng& rng, DType dtype) {
    G2L_CHECK(fan_in > 0, "uniform_init: fan_in must be > 0, got ", fan_in);
    // U(-1/sqrt(fan_in), 1/sqrt(fan_in)) is PyTorch's default for Linear/Conv weights and biases,
    // the initialisation the reference G2L-Net was trained with.
    const double bound = 1.0 / std::sqrt(double(fan_in));
    return Tensor::rand(shape, rng, -bound, bound, dtype);
}

void Module::apply(const std::function<void(Module&)>& fn) {
    fn(*this);
    for (auto& [name, child] : children_) child->apply(fn);
}

}  // namespace g2l::nn
