// SPDX-License-Identifier: MIT
// Tensor: a value handle to an n-dimensional array with reverse-mode autograd.
//
// ALIASING: copying a Tensor copies the handle, not the data (like flashlight's Variable and
// PyTorch). `clone()` copies the data. `detach()` returns a handle to the same data without
// autograd history.
//
// Memory layout: every tensor is dense and row-major (contiguous). `reshape` is a view on the
// same storage; `slice`, `transpose` and friends (nn/ops) copy. Kernels therefore always see
// contiguous data and take plain pointers + sizes.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

#include "core/dtype.h"
#include "core/error.h"
#include "core/storage.h"

namespace g2l {

class Rng;
namespace autograd {
struct Node;
}

struct TensorImpl;

class Tensor {
public:
    /// An undefined tensor (defined() == false). Most calls on it throw.
    Tensor() = default;
    explicit Tensor(std::shared_ptr<TensorImpl> impl) : impl_(std::move(impl)) {}

    // ---- factories (CPU unless a device is given) ----
    /// Uninitialised memory.
    static Tensor empty(const Shape& shape, DType dtype = DType::F32, Device dev = Device::cpu());
    static Tensor zeros(const Shape& shape, DType dtype = DType::F32, Device dev = Device::cpu());
    static Tensor ones(const Shape& shape, DType dtype = DType::F32, Device dev = Device::cpu());
    static Tensor full(const Shape& shape, double value, DType dtype = DType::F32,
                       Device dev = Device::cpu());
    /// Copies `values` (row-major) into a new CPU tensor; throws if the count != numel(shape).
    template <class T>
    static Tensor from_vector(const std::vector<T>& values, const Shape& shape);
    /// Standard normal (mean 0, std 1) from `rng`.
    static Tensor randn(const Shape& shape, Rng& rng, DType dtype = DType::F32);
    /// Uniform in [lo, hi) from `rng`.
    static Tensor rand(const Shape& shape, Rng& rng, double lo = 0.0, double hi = 1.0,
                       DType dtype = DType::F32);
    /// A 0-d tensor holding `value`.
    static Tensor scalar(double value, DType dtype = DType::F32);

    // ---- metadata ----
    bool defined() const { return impl_ != nullptr; }
    const Shape& shape() const;
    int64_t dim() const { return int64_t(shape().size()); }
    /// Size of dimension `d`; negative d counts from the end. Throws naming the shape if out of range.
    int64_t size(int64_t d) const;
    int64_t numel() const;
    DType dtype() const;
    Device device() const;
    size_t nbytes() const { return size_t(numel()) * dtype_size(dtype()); }
    /// Element strides per dimension. Tensors are always dense row-major, so these are the
    /// row-major strides of shape() (kept for kernels and future strided views).
    Shape strides() const;
    /// "f32[2, 3] cpu" for messages.
    std::string desc() const;

    // ---- data access (borrowed pointers: never store them) ----
    void* data();
    const void* data() const;
    /// Typed pointer; throws if T does not match dtype().
    template <class T> T* data();
    template <class T> const T* data() const;
    /// The single value of a 1-element CPU tensor (any dtype converted to T).
    template <class T> T item() const;
    /// Copies to a std::vector<T> (CPU or CUDA source; dtype must match T).
    template <class T> std::vector<T> to_vector() const;

    // ---- copies, views, devices ----
    /// Deep copy (same device, dtype); no autograd history.
    Tensor clone() const;
    /// Same data, no autograd history, requires_grad false.
    Tensor detach() const;
    /// Copy to another device (synchronous). Returns *this if already there.
    Tensor to(Device dev) const;
    /// Converts the dtype (CPU). Differentiable between F32 and F64.
    Tensor to(DType dtype) const;
    /// A view with a new shape (same numel); one dimension may be -1. Differentiable.
    Tensor reshape(const Shape& shape) const;
    /// Writes `value` into every element (in place; bumps the storage version).
    void fill_(double value);
    /// Copies the data of `src` (same shape and dtype, any device) into this tensor, in place.
    void copy_(const Tensor& src);

    // ---- autograd ----
    bool requires_grad() const;
    /// Marks a leaf as a parameter whose gradient backward() accumulates into grad().
    Tensor& set_requires_grad(bool on = true);
    /// The accumulated gradient (undefined until a backward reaches this leaf).
    Tensor grad() const;
    /// Resets grad() to undefined.
    void zero_grad();
    /// Sets grad() (used by optimizers / checkpoint tools); shape and dtype must match.
    void set_grad(const Tensor& g);
    bool is_leaf() const;
    const std::shared_ptr<autograd::Node>& grad_fn() const;
    /// Runs reverse-mode differentiation from this tensor. Without `grad` the tensor must have
    /// one element (the seed is 1). Frees the graph unless retain_graph.
    void backward(const Tensor& grad = Tensor(), bool retain_graph = false) const;

    /// Storage version (incremented by in-place writes).
    uint64_t version() const;
    /// The same storage (aliasing test).
    bool shares_storage_with(const Tensor& other) const;

    TensorImpl* impl() const { return impl_.get(); }
    const std::shared_ptr<TensorImpl>& impl_ptr() const { return impl_; }

private:
    void check_defined(const char* what) const;
    std::shared_ptr<TensorImpl> impl_;
};

/// The data behind a Tensor handle. Only core/ touches it directly.
struct TensorImpl {
    std::shared_ptr<Storage> storage;
    int64_t offset = 0;  ///< in elements
    Shape shape;
    DType dtype = DType::F32;
    bool requires_grad = false;
    std::shared_ptr<TensorImpl> grad;
    std::shared_ptr<autograd::Node> grad_fn;
};

// ---- template definitions ----
template <class T>
Tensor Tensor::from_vector(const std::vector<T>& values, const Shape& shape) {
    G2L_CHECK(int64_t(values.size()) == shape_numel(shape), "Tensor::from_vector: ",
              values.size(), " values for shape ", shape_str(shape), " (needs ",
              shape_numel(shape), ")");
    Tensor t = empty(shape, dtype_of<T>());
    T* p = t.data<T>();
    for (size_t i = 0; i < values.size(); ++i) p[i] = values[i];
    return t;
}

template <class T>
T* Tensor::data() {
    G2L_CHECK(dtype() == dtype_of<T>(), "Tensor::data<", dtype_name(dtype_of<T>()),
              ">: tensor is ", desc());
    return static_cast<T*>(data());
}

template <class T>
const T* Tensor::data() const {
    G2L_CHECK(dtype() == dtype_of<T>(), "Tensor::data<", dtype_name(dtype_of<T>()),
              ">: tensor is ", desc());
    return static_cast<const T*>(data());
}

template <class T>
std::vector<T> Tensor::to_vector() const {
    const Tensor c = to(Device::cpu());
    const T* p = c.data<T>();
    return std::vector<T>(p, p + c.numel());
}

}  // namespace g2l
