// SPDX-License-Identifier: MIT
#include "core/autograd.h"

#include <unordered_map>
#include <unordered_set>

#include "core/device_cuda.h"

namespace g2l::autograd {

namespace {
// Per thread (like PyTorch's grad mode): a NoGradGuard on one thread does not stop another
// thread from recording its graph.
thread_local bool t_grad_enabled = true;
}

bool grad_enabled() { return t_grad_enabled; }
NoGradGuard::NoGradGuard() : prev_(t_grad_enabled) { t_grad_enabled = false; }
NoGradGuard::~NoGradGuard() { t_grad_enabled = prev_; }

bool needs_grad(const std::vector<Tensor>& inputs) {
    if (!t_grad_enabled) return false;
    for (const Tensor& t : inputs)
        if (t.defined() && t.requires_grad()) return true;
    return false;
}

Tensor record(const char* op, Tensor out, std::vector<Tensor> inputs, BackwardFn fn) {
    // No node at all when nothing upstream is trainable, so inference pays no closure allocation.
    if (!needs_grad(inputs)) return out;
    auto node = std::make_shared<Node>();
    node->op = op;
    node->versions.reserve(inputs.size());
    // Snapshot of the inputs' storage versions; run_backward compares them to catch an input that
    // was modified in place between forward and backward.
    for (const Tensor& t : inputs) node->versions.push_back(t.defined() ? t.version() : 0);
    node->inputs = std::move(inputs);
    node->fn = std::move(fn);
    out.impl()->grad_fn = std::move(node);
    out.impl()->requires_grad = true;
    return out;
}

Grads::Grads(const char* op, const std::vector<Tensor>& inputs)
    : op_(op), inputs_(inputs), slots_(inputs.size()) {}

bool Grads::needs(size_t i) const {
    return i < inputs_.size() && inputs_[i].defined() && inputs_[i].requires_grad();
}

void Grads::add(size_t i, const Tensor& dx) {
    G2L_CHECK(i < inputs_.size(), op_, " backward: gradient for input ", i, " but the op has ",
              inputs_.size(), " inputs");
    const Tensor& in = inputs_[i];
    G2L_CHECK(dx.shape() == in.shape() && dx.dtype() == in.dtype() && dx.device() == in.device(),
              op_, " backward: gradient ", dx.desc(), " does not match input ", i, " ",
              in.desc());
    if (!slots_[i].defined()) {
        slots_[i] = dx;
    } else {
        // The first gradient is kept by reference and may alias a tensor the closure still uses
        // (often dout itself), so the sum goes into a fresh copy instead of into that buffer.
        Tensor sum = slots_[i].clone();
        accumulate(sum, dx);
        slots_[i] = sum;
    }
}

void accumulate(Tensor& dst, const Tensor& src) {
    const int64_t n = dst.numel();
    if (dst.device().is_cuda()) {
        if (dst.dtype() == DType::F32)
            cuda::accumulate_f32(dst.data<float>(), src.data<float>(), n);
        else
            cuda::accumulate_f64(dst.data<double>(), src.data<double>(), n);
        return;
    }
    if (dst.dtype() == DType::F32) {
        float* d = dst.data<float>();
        const float* s = src.data<float>();
        for (int64_t i = 0; i < n; ++i) d[i] += s[i];
    } else if (dst.dtype() == DType::F64) {
        double* d = dst.data<double>();
        const double* s = src.data<double>();
        for (int64_t i = 0; i < n; ++i) d[i] += s[i];
    } else {
        G2L_CHECK(false, "autograd: gradients of ", dst.desc(), " are not supported");
    }
}

namespace {

struct Pending {
    Tensor grad;
    bool owned = false;  // grad is our private buffer and may be updated in place
};

void add_pending(Pending& p, const Tensor& g) {
    // First contribution: borrow it without copying (most tensors have a single consumer). It may
    // alias another node's gradient, so a second contribution first clones it; `owned` makes that
    // clone happen once, and later contributions add in place.
    if (!p.grad.defined()) {
        p.grad = g;
        p.owned = false;
    } else {
        if (!p.owned) {
            p.grad = p.grad.clone();
            p.owned = true;
        }
        accumulate(p.grad, g);
    }
}

void add_to_leaf(TensorImpl* leaf, const Tensor& g) {
    // A leaf's .grad outlives this backward and later backward passes add into it in place, so it
    // must own its buffer rather than alias a temporary of this pass.
    if (!leaf->grad) {
        leaf->grad = g.clone().impl_ptr();
    } else {
        Tensor dst(leaf->grad);
        accumulate(dst, g);
    }
}

}  // namespace

void run_backward(const Tensor& root, const Tensor& seed_in, bool retain_graph) {
    G2L_CHECK(root.defined(), "backward: undefined tensor");
    G2L_CHECK(root.requires_grad(), "backward: tensor ", root.desc(),
              " does not require grad (no parameter or input with requires_grad reaches it)");
    Tensor seed = seed_in;
    if (!seed.defined()) {
        G2L_CHECK(root.numel() == 1, "backward: without an explicit gradient the tensor must "
                                     "have one element, got ", root.desc());
        seed = Tensor::ones(root.shape(), root.dtype(), root.device());
    }
    G2L_CHECK(seed.shape() == root.shape() && seed.dtype() == root.dtype(),
              "backward: gradient ", seed.desc(), " does not match tensor ", root.desc());

    // Iterative post-order DFS over non-leaf tensors gives a topological order. `order` holds
    // strong references: freeing a node's inputs below may drop the last other reference.
    std::vector<std::shared_ptr<TensorImpl>> order;
    std::unordered_set<TensorImpl*> seen;
    std::vector<std::pair<std::shared_ptr<TensorImpl>, size_t>> stack;
    if (root.impl()->grad_fn) {
        stack.push_back({root.impl_ptr(), 0});
        seen.insert(root.impl());
    }
    while (!stack.empty()) {
        auto& [t, next] = stack.back();
        Node& node = *t->grad_fn;
        G2L_CHECK(!node.released, "backward: the graph through op '", node.op,
                  "' was already freed by an earlier backward (pass retain_graph=true)");
        if (next < node.inputs.size()) {
            std::shared_ptr<TensorImpl> in = node.inputs[next++].impl_ptr();
            if (in && in->requires_grad && in->grad_fn && !seen.count(in.get())) {
                seen.insert(in.get());
                stack.push_back({std::move(in), 0});
            }
        } else {
            order.push_back(std::move(t));
            stack.pop_back();
        }
    }

    std::unordered_map<TensorImpl*, Pending> pending;
    if (root.impl()->grad_fn) {
        pending[root.impl()].grad = seed;
    } else {
        add_to_leaf(root.impl(), seed);  // backward on a leaf: its gradient is the seed
        return;
    }
    // Reverse post-order: every consumer of a tensor runs before the tensor's own node, so its
    // pending gradient is complete by the time we reach it.
    for (auto it = order.rbegin(); it != order.rend(); ++it) {
        TensorImpl* t = it->get();
        auto found = pending.find(t);
        if (found == pending.end()) continue;  // no gradient flows into this tensor
        const Tensor dout = found->second.grad;
        // Drop the entry now so each intermediate gradient is freed as soon as it is consumed.
        pending.erase(found);
        Node& node = *t->grad_fn;
        for (size_t i = 0; i < node.inputs.size(); ++i) {
            const Tensor& in = node.inputs[i];
            G2L_CHECK(!in.defined() || in.version() == node.versions[i], "backward of op '",
                      node.op, "': input ", i, " ", in.desc(),
                      " was modified in place after the op used it");
        }
        Grads grads(node.op, node.inputs);
        node.fn(dout, grads);
        // A closure may fill slots for inputs that need no gradient; those are dropped here.
        for (size_t i = 0; i < node.inputs.size(); ++i) {
            const Tensor& g = grads.slots()[i];
            if (!g.defined() || !grads.needs(i)) continue;
            TensorImpl* in = node.inputs[i].impl();
            if (in->grad_fn)
                add_pending(pending[in], g);
            else
                add_to_leaf(in, g);
        }
        // Releasing the closure and inputs frees the saved activations; `released` makes a second
        // backward through this node throw instead of silently producing no gradient.
        if (!retain_graph) {
            node.fn = nullptr;
            node.inputs.clear();
            node.released = true;
        }
    }
}

}  // namespace g2l::autograd
