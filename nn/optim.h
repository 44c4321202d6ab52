// SPDX-License-Identifier: MIT
// Adam / AdamW optimiser over named parameter groups (PyTorch semantics, amsgrad off).
//
// Each group scales the base learning rate by its lr_mult (the official G2L-Net code gives the
// seg / T-net / EVF / residual networks x1, x10, x1, x20) and has its own weight decay.
// Gradients accumulate in Tensor::grad() across backward() calls; zero_grad() resets them.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/tensor.h"

namespace g2l::nn {

/// Named parameters sharing a learning-rate multiplier and a weight decay.
struct ParamGroup {
    std::string name;                                     ///< for messages ("tnet", "seg", ...)
    std::vector<std::pair<std::string, Tensor>> params;   ///< (unique name, leaf parameter)
    double lr_mult = 1.0;                                 ///< group lr = base lr x lr_mult
    double weight_decay = 0.0;                            ///< L2 or decoupled (AdamW) decay
};

/// Hyper-parameters shared by all groups (the G2L-Net code uses betas (0.9, 0.99)).
struct AdamOptions {
    double lr = 1e-3;
    double beta1 = 0.9;
    double beta2 = 0.999;
    double eps = 1e-8;
    bool decoupled = false;  ///< false: Adam (decay added to the gradient); true: AdamW
};

/// Adam with per-parameter first/second moments m, v (same dtype and shape as the parameter)
/// and a per-parameter step count t, as torch.optim.Adam keeps them: a parameter whose grad is
/// undefined at step() is skipped entirely (p, m, v and t unchanged), so its bias correction
/// 1 - beta^t counts only the steps in which it had a gradient.
///
/// Parameters are held by handle (aliasing): step() writes into the caller's tensors in place,
/// under autograd::NoGradGuard, and bumps their storage version (so a graph recorded before
/// the step refuses to run backward on the modified values). CPU tensors only for now.
class Adam {
public:
    /// Throws g2l::Error naming the group / parameter when: there is no parameter, a group is
    /// empty, a name repeats (across all groups) or is empty, two parameters share storage, a
    /// parameter is undefined, not a leaf, does not require grad, is not f32/f64 or not on the
    /// CPU; or when lr, lr_mult, weight_decay, eps are negative / not finite or a beta is not
    /// in [0, 1).
    Adam(std::vector<ParamGroup> groups, AdamOptions options);

    /// One update of every parameter that has a gradient (see class comment). Throws if a
    /// gradient's shape, dtype or device does not match its parameter.
    void step();
    /// Resets every parameter's gradient to undefined (PyTorch zero_grad(set_to_none=True)).
    void zero_grad();
    /// Sets the base learning rate (each group uses base_lr x lr_mult). Throws if base_lr < 0
    /// or not finite.
    void set_lr(double base_lr);
    /// The base learning rate.
    double lr() const { return opt_.lr; }
    /// Number of step() calls since construction (or the value given to load_state).
    int64_t step_count() const { return step_count_; }
    /// The groups as given (the parameter handles alias the caller's tensors).
    const std::vector<ParamGroup>& groups() const { return groups_; }

    /// The optimiser state, for checkpoints: for each parameter <p> (group order),
    /// "adam.m.<p>" and "adam.v.<p>" (the moments, parameter shape/dtype) and "adam.step.<p>"
    /// (i32 [1]: that parameter's own step count t). Tensors are detached clones.
    /// The global step_count() is not a tensor: store it in the checkpoint metadata.
    std::vector<std::pair<std::string, Tensor>> state_tensors() const;

    /// Restores the state written by state_tensors() (other keys in `state`, e.g. the model's
    /// weights, are ignored) and sets step_count() = step. Throws one g2l::Error listing every
    /// missing "adam.*" name, every shape/dtype mismatch, and every "adam.*" name that matches
    /// no parameter; nothing is modified unless everything matches.
    void load_state(const std::map<std::string, Tensor>& state, int64_t step);

private:
    struct Slot {
        Tensor m, v;
        int64_t t = 0;
    };
    std::vector<ParamGroup> groups_;
    AdamOptions opt_;
    std::vector<std::vector<Slot>> slots_;  ///< slots_[group][param]
    int64_t step_count_ = 0;
};

}  // namespace g2l::nn
