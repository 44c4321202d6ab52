// SPDX-License-Identifier: MIT
// Module: owns named parameters, buffers and child modules; gives a state dict with dotted
// names ("backbone.conv1.weight"). Forward functions are ordinary member functions of each
// module type (no virtual forward: signatures differ).
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/rng.h"
#include "core/tensor.h"

namespace g2l::nn {

using NamedTensors = std::vector<std::pair<std::string, Tensor>>;

class Module {
public:
    virtual ~Module() = default;

    /// Parameters of this module and its children, depth first, in registration order.
    NamedTensors named_parameters() const;
    /// Buffers (e.g. BatchNorm running statistics), same order rules.
    NamedTensors named_buffers() const;
    std::vector<Tensor> parameters() const;
    /// Parameters and buffers by dotted name.
    std::map<std::string, Tensor> state_dict() const;
    /// Copies values into this module's tensors. strict: every name must match both ways.
    /// Throws one error listing every missing, unexpected and shape/dtype-mismatched name.
    void load_state_dict(const std::map<std::string, Tensor>& sd, bool strict = true);
    /// Training mode (batch statistics, dropout) vs eval; recursive.
    void train(bool on = true);
    void eval() { train(false); }
    bool is_training() const { return training_; }
    /// Number of parameter elements.
    int64_t num_parameters() const;
    /// Clears the gradients of all parameters.
    void zero_grad();
    /// Calls fn on this module and then on every descendant, depth first.
    void apply(const std::function<void(Module&)>& fn);

protected:
    /// Registers a leaf parameter (requires_grad is set) and returns the same handle.
    Tensor register_parameter(const std::string& name, Tensor t);
    /// Registers a buffer (no gradient) and returns the same handle.
    Tensor register_buffer(const std::string& name, Tensor t);
    template <class M>
    std::shared_ptr<M> register_module(const std::string& name, std::shared_ptr<M> m) {
        add_child(name, m);
        return m;
    }

private:
    void add_child(const std::string& name, std::shared_ptr<Module> m);
    void check_new_name(const std::string& name) const;
    void collect(const std::string& prefix, bool params, NamedTensors& out) const;

    NamedTensors params_, buffers_;
    std::vector<std::pair<std::string, std::shared_ptr<Module>>> children_;
    bool training_ = true;
};

/// PyTorch's default init for Linear/Conv: weight and bias ~ U(-1/sqrt(fan_in), 1/sqrt(fan_in)).
Tensor uniform_init(const Shape& shape, int64_t fan_in, Rng& rng, DType dtype = DType::F32);

}  // namespace g2l::nn
