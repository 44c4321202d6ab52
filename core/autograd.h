// SPDX-License-Identifier: MIT
// Reverse-mode autograd: ops record a Node (inputs + a backward closure) on their output;
// Tensor::backward() walks the graph in reverse topological order and accumulates gradients.
//
// Rules for op authors (nn/ops):
//  - Call record() only after computing the output; it is a no-op when no input requires grad
//    or grad mode is off (NoGradGuard), so closures cost nothing at inference.
//  - A closure captures only what backward needs, and NEVER the output Tensor itself (that
//    would be a reference cycle): capture `out.detach()` instead.
//  - Backward adds into gradients: call grads.add(i, dx) once per input that needs it
//    (grads.needs(i)); add() checks that dx has the input's shape and dtype.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/tensor.h"

namespace g2l::autograd {

/// Gradients produced by one node's backward, one slot per input.
class Grads {
public:
    Grads(const char* op, const std::vector<Tensor>& inputs);
    /// Whether input i needs a gradient (skip computing it otherwise).
    bool needs(size_t i) const;
    /// Adds dx to input i's gradient; throws naming the op if shape/dtype/device differ.
    void add(size_t i, const Tensor& dx);
    std::vector<Tensor>& slots() { return slots_; }

private:
    const char* op_;
    const std::vector<Tensor>& inputs_;
    std::vector<Tensor> slots_;
};

using BackwardFn = std::function<void(const Tensor& dout, Grads& grads)>;

/// One recorded operation.
struct Node {
    const char* op = "";
    std::vector<Tensor> inputs;
    std::vector<uint64_t> versions;  ///< storage versions of the inputs at record time
    BackwardFn fn;
    bool released = false;  ///< graph freed by a previous backward
};

/// True unless a NoGradGuard is alive on this thread.
bool grad_enabled();

/// Disables graph recording while alive (inference, optimizer steps, running statistics).
class NoGradGuard {
public:
    NoGradGuard();
    ~NoGradGuard();
    NoGradGuard(const NoGradGuard&) = delete;
    NoGradGuard& operator=(const NoGradGuard&) = delete;

private:
    bool prev_;
};

/// True if grad mode is on and any defined input requires grad.
bool needs_grad(const std::vector<Tensor>& inputs);

/// Attaches a backward node to `out` when needs_grad(inputs); returns `out`.
Tensor record(const char* op, Tensor out, std::vector<Tensor> inputs, BackwardFn fn);

/// dst += src elementwise (CPU or CUDA, f32/f64). Shapes must match (checked by the caller).
void accumulate(Tensor& dst, const Tensor& src);

/// Implementation of Tensor::backward.
void run_backward(const Tensor& root, const Tensor& seed, bool retain_graph);

}  // namespace g2l::autograd
