// SPDX-License-Identifier: MIT
#include "core/tensor.h"

#include <cstring>

#include "core/autograd.h"
#include "core/device_cuda.h"
#include "core/rng.h"

namespace g2l {

namespace {

std::shared_ptr<TensorImpl> make_impl(const Shape& shape, DType dtype, Device dev) {
    for (int64_t d : shape)
        G2L_CHECK(d >= 0, "Tensor: negative size in shape ", shape_str(shape));
    auto impl = std::make_shared<TensorImpl>();
    impl->shape = shape;
    impl->dtype = dtype;
    impl->storage = std::make_shared<Storage>(size_t(shape_numel(shape)) * dtype_size(dtype), dev);
    return impl;
}

template <class T>
void fill_cpu(void* p, int64_t n, double v) {
    T* d = static_cast<T*>(p);
    const T tv = static_cast<T>(v);
    for (int64_t i = 0; i < n; ++i) d[i] = tv;
}

void fill_any(void* p, int64_t n, DType dt, double v) {
    switch (dt) {
        case DType::F32: fill_cpu<float>(p, n, v); break;
        case DType::F64: fill_cpu<double>(p, n, v); break;
        case DType::I32: fill_cpu<int32_t>(p, n, v); break;
    }
}

void copy_bytes(void* dst, Device ddev, const void* src, Device sdev, size_t n) {
    if (n == 0) return;
    if (ddev.is_cpu() && sdev.is_cpu()) std::memcpy(dst, src, n);
    else if (ddev.is_cuda() && sdev.is_cpu()) cuda::copy_host_to_device(dst, src, n);
    else if (ddev.is_cpu() && sdev.is_cuda()) cuda::copy_device_to_host(dst, src, n);
    else cuda::copy_device_to_device(dst, src, n);
}

}  // namespace

// ---- factories ----
Tensor Tensor::empty(const Shape& shape, DType dtype, Device dev) {
    return Tensor(make_impl(shape, dtype, dev));
}

Tensor Tensor::zeros(const Shape& shape, DType dtype, Device dev) {
    Tensor t = empty(shape, dtype, dev);
    if (dev.is_cpu()) std::memset(t.data(), 0, t.nbytes());
    else cuda::memset_zero(t.data(), t.nbytes());
    return t;
}

Tensor Tensor::ones(const Shape& shape, DType dtype, Device dev) {
    return full(shape, 1.0, dtype, dev);
}

Tensor Tensor::full(const Shape& shape, double value, DType dtype, Device dev) {
    // There is no CUDA fill kernel (only memset_zero), so the values are made on the CPU and
    // copied.
    Tensor t = empty(shape, dtype, Device::cpu());
    fill_any(t.data(), t.numel(), dtype, value);
    return dev.is_cpu() ? t : t.to(dev);
}

Tensor Tensor::randn(const Shape& shape, Rng& rng, DType dtype) {
    Tensor t = empty(shape, dtype);
    const int64_t n = t.numel();
    if (dtype == DType::F32) {
        float* p = t.data<float>();
        for (int64_t i = 0; i < n; ++i) p[i] = float(rng.normal());
    } else {
        G2L_CHECK(dtype == DType::F64, "Tensor::randn: dtype must be f32 or f64, got ",
                  dtype_name(dtype));
        double* p = t.data<double>();
        for (int64_t i = 0; i < n; ++i) p[i] = rng.normal();
    }
    return t;
}

Tensor Tensor::rand(const Shape& shape, Rng& rng, double lo, double hi, DType dtype) {
    G2L_CHECK(hi >= lo, "Tensor::rand: empty range [", lo, ", ", hi, ")");
    Tensor t = empty(shape, dtype);
    const int64_t n = t.numel();
    if (dtype == DType::F32) {
        float* p = t.data<float>();
        for (int64_t i = 0; i < n; ++i) p[i] = float(rng.uniform(lo, hi));
    } else if (dtype == DType::F64) {
        double* p = t.data<double>();
        for (int64_t i = 0; i < n; ++i) p[i] = rng.uniform(lo, hi);
    } else {
        int32_t* p = t.data<int32_t>();
        for (int64_t i = 0; i < n; ++i) p[i] = int32_t(rng.randint(int64_t(lo), int64_t(hi)));
    }
    return t;
}

Tensor Tensor::scalar(double value, DType dtype) { return full({}, value, dtype); }

// ---- metadata ----
void Tensor::check_defined(const char* what) const {
    G2L_CHECK(impl_ != nullptr, "Tensor::", what, ": tensor is undefined");
}

const Shape& Tensor::shape() const {
    check_defined("shape");
    return impl_->shape;
}

int64_t Tensor::size(int64_t d) const {
    const int64_t n = dim();
    // Negative dimensions count from the end, as in PyTorch: size(-1) is the last dimension.
    const int64_t k = d < 0 ? d + n : d;
    G2L_CHECK(k >= 0 && k < n, "Tensor::size: dimension ", d, " out of range for shape ",
              shape_str(shape()));
    return impl_->shape[size_t(k)];
}

int64_t Tensor::numel() const { return shape_numel(shape()); }

Shape Tensor::strides() const {
    const Shape& s = shape();
    Shape st(s.size(), 1);
    for (size_t i = s.size(); i-- > 1;) st[i - 1] = st[i] * s[i];
    return st;
}

DType Tensor::dtype() const {
    check_defined("dtype");
    return impl_->dtype;
}

Device Tensor::device() const {
    check_defined("device");
    return impl_->storage->device();
}

std::string Tensor::desc() const {
    if (!impl_) return "undefined";
    return cat(dtype_name(impl_->dtype), shape_str(impl_->shape), " ", device().str());
}

void* Tensor::data() {
    check_defined("data");
    return static_cast<char*>(impl_->storage->data()) + impl_->offset * dtype_size(impl_->dtype);
}

const void* Tensor::data() const {
    check_defined("data");
    return static_cast<const char*>(impl_->storage->data()) +
           impl_->offset * dtype_size(impl_->dtype);
}

template <class T>
T Tensor::item() const {
    G2L_CHECK(numel() == 1, "Tensor::item: needs exactly one element, got ", desc());
    // Copies (and waits for) a CUDA value; a no-op alias on the CPU.
    const Tensor c = to(Device::cpu());
    switch (c.dtype()) {
        case DType::F32: return static_cast<T>(*static_cast<const float*>(c.data()));
        case DType::F64: return static_cast<T>(*static_cast<const double*>(c.data()));
        case DType::I32: return static_cast<T>(*static_cast<const int32_t*>(c.data()));
    }
    return T();
}
template float Tensor::item<float>() const;
template double Tensor::item<double>() const;
template int32_t Tensor::item<int32_t>() const;
template int64_t Tensor::item<int64_t>() const;

// ---- copies, views, devices ----
Tensor Tensor::clone() const {
    Tensor out = empty(shape(), dtype(), device());
    copy_bytes(out.data(), device(), data(), device(), nbytes());
    return out;
}

Tensor Tensor::detach() const {
    check_defined("detach");
    // A fresh impl sharing the storage but with no grad_fn, requires_grad or grad: backward
    // closures capture outputs this way to avoid a Node -> output -> Node reference cycle.
    auto impl = std::make_shared<TensorImpl>();
    impl->storage = impl_->storage;
    impl->offset = impl_->offset;
    impl->shape = impl_->shape;
    impl->dtype = impl_->dtype;
    return Tensor(impl);
}

Tensor Tensor::to(Device dev) const {
    // Same device: alias, no copy and no graph node.
    if (dev == device()) return *this;
    Tensor out = empty(shape(), dtype(), dev);
    copy_bytes(out.data(), dev, data(), device(), nbytes());
    return autograd::record("to_device", out, {*this}, [src = device()](const Tensor& d,
                                                                         autograd::Grads& g) {
        g.add(0, d.to(src));
    });
}

Tensor Tensor::to(DType dt) const {
    if (dt == dtype()) return *this;
    // There is no CUDA cast kernel; casts happen on the CPU (f64 is a CPU test dtype anyway).
    G2L_CHECK(device().is_cpu(), "Tensor::to(dtype): only on cpu, tensor is ", desc());
    Tensor out = empty(shape(), dt);
    const int64_t n = numel();
    auto conv = [&](auto* dst) {
        using D = std::remove_pointer_t<decltype(dst)>;
        switch (dtype()) {
            case DType::F32: { const float* s = data<float>(); for (int64_t i = 0; i < n; ++i) dst[i] = D(s[i]); break; }
            case DType::F64: { const double* s = data<double>(); for (int64_t i = 0; i < n; ++i) dst[i] = D(s[i]); break; }
            case DType::I32: { const int32_t* s = data<int32_t>(); for (int64_t i = 0; i < n; ++i) dst[i] = D(s[i]); break; }
        }
    };
    switch (dt) {
        case DType::F32: conv(out.data<float>()); break;
        case DType::F64: conv(out.data<double>()); break;
        case DType::I32: conv(out.data<int32_t>()); break;
    }
    const DType src = dtype();
    if (src == DType::I32 || dt == DType::I32) return out;  // not differentiable
    return autograd::record("to_dtype", out, {*this}, [src](const Tensor& d, autograd::Grads& g) {
        g.add(0, d.to(src));
    });
}

Tensor Tensor::reshape(const Shape& new_shape) const {
    Shape s = new_shape;
    int64_t known = 1, infer = -1;
    for (size_t i = 0; i < s.size(); ++i) {
        if (s[i] == -1) {
            G2L_CHECK(infer < 0, "reshape: more than one -1 in ", shape_str(new_shape));
            infer = int64_t(i);
        } else {
            G2L_CHECK(s[i] >= 0, "reshape: bad size in ", shape_str(new_shape));
            known *= s[i];
        }
    }
    if (infer >= 0) {
        G2L_CHECK(known > 0 && numel() % known == 0, "reshape: cannot reshape ", desc(),
                  " to ", shape_str(new_shape));
        s[size_t(infer)] = numel() / known;
    }
    G2L_CHECK(shape_numel(s) == numel(), "reshape: cannot reshape ", desc(), " (", numel(),
              " elements) to ", shape_str(new_shape));
    // Tensors are always dense row-major, so every reshape is a view of the same storage; the
    // recorded node reconnects the view to the graph.
    Tensor out = detach();
    out.impl()->shape = s;
    const Shape old = shape();
    return autograd::record("reshape", out, {*this}, [old](const Tensor& d, autograd::Grads& g) {
        g.add(0, d.reshape(old));
    });
}

void Tensor::fill_(double value) {
    // Overwriting a trainable leaf while recording would make the gradients silently wrong; such
    // writes (init, optimizer, loading) must run under NoGradGuard.
    G2L_CHECK(!(requires_grad() && autograd::grad_enabled() && is_leaf()),
              "fill_: in-place write to a leaf that requires grad; use NoGradGuard");
    if (device().is_cpu()) {
        fill_any(data(), numel(), dtype(), value);
    } else {
        copy_(full(shape(), value, dtype()));
    }
    // Any node that saved this storage now fails its version check instead of using new values.
    impl_->storage->bump_version();
}

void Tensor::copy_(const Tensor& src) {
    G2L_CHECK(src.shape() == shape() && src.dtype() == dtype(), "copy_: source ", src.desc(),
              " does not match destination ", desc());
    copy_bytes(data(), device(), src.data(), src.device(), nbytes());
    impl_->storage->bump_version();
}

// ---- autograd ----
bool Tensor::requires_grad() const {
    check_defined("requires_grad");
    return impl_->requires_grad;
}

Tensor& Tensor::set_requires_grad(bool on) {
    check_defined("set_requires_grad");
    G2L_CHECK(is_leaf(), "set_requires_grad: only leaves (tensors not produced by a recorded op)"
                         " can be marked, got ", desc());
    G2L_CHECK(!on || dtype() != DType::I32, "set_requires_grad: integer tensor ", desc(),
              " cannot require grad");
    impl_->requires_grad = on;
    return *this;
}

Tensor Tensor::grad() const {
    check_defined("grad");
    return impl_->grad ? Tensor(impl_->grad) : Tensor();
}

void Tensor::zero_grad() {
    check_defined("zero_grad");
    // Dropped rather than zero-filled: the next backward stores a fresh copy (add_to_leaf), and a
    // parameter that gets no gradient stays undefined instead of holding zeros.
    impl_->grad.reset();
}

void Tensor::set_grad(const Tensor& g) {
    check_defined("set_grad");
    if (!g.defined()) { impl_->grad.reset(); return; }
    G2L_CHECK(g.shape() == shape() && g.dtype() == dtype(), "set_grad: gradient ", g.desc(),
              " does not match ", desc());
    impl_->grad = g.impl_ptr();
}

bool Tensor::is_leaf() const {
    check_defined("is_leaf");
    return impl_->grad_fn == nullptr;
}

const std::shared_ptr<autograd::Node>& Tensor::grad_fn() const {
    check_defined("grad_fn");
    return impl_->grad_fn;
}

void Tensor::backward(const Tensor& grad, bool retain_graph) const {
    autograd::run_backward(*this, grad, retain_graph);
}

uint64_t Tensor::version() const {
    check_defined("version");
    return impl_->storage->version();
}

bool Tensor::shares_storage_with(const Tensor& other) const {
    return impl_ && other.impl_ && impl_->storage == other.impl_->storage;
}

}  // namespace g2l
