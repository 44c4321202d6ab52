// SPDX-License-Identifier: MIT
#include "nn/ops/shape.h"

#include <algorithm>

#include "core/autograd.h"
#include "kernels/reduce.h"
#include "kernels/shape.h"
#include "nn/ops/dim_utils.h"

namespace g2l::nn {

namespace {

void check_input(const char* op, const Tensor& x) {
    G2L_CHECK(x.defined(), op, ": input is undefined");
}

// dim for inserting a new axis into a rank-r tensor: [-(r+1), r].
int64_t wrap_insert_dim(const char* op, int64_t dim, const Shape& s) {
    const int64_t r = int64_t(s.size());
    G2L_CHECK(dim >= -(r + 1) && dim <= r, op, ": dim ", dim,
              " is out of range for inserting into ", shape_str(s), " (valid: ", -(r + 1), " .. ",
              r, ")");
    return dim < 0 ? dim + r + 1 : dim;
}

// Copies rows [off, off + len) of src [outer, src_D, inner] into dst [outer, dst_D, inner] at
// dst_off (the common step of concat, slice and their gradients).
void copy_slab(const Tensor& src, int64_t src_D, int64_t src_off, Tensor& dst, int64_t dst_D,
               int64_t dst_off, int64_t outer, int64_t len, int64_t inner) {
    kernels::copy_slab(src, src_D, src_off, dst, dst_D, dst_off, outer, len, inner);
}

Tensor permute_raw(const Tensor& x, const std::vector<int64_t>& perm) {
    Shape out(perm.size());
    for (size_t k = 0; k < perm.size(); ++k) out[k] = x.shape()[size_t(perm[k])];
    Tensor y = Tensor::empty(out, x.dtype(), x.device());
    kernels::permute(x, perm, y);
    return y;
}

}  // namespace

Tensor concat(const std::vector<Tensor>& xs, int64_t dim) {
    G2L_CHECK(!xs.empty(), "concat: no tensors given");
    for (const Tensor& x : xs) check_input("concat", x);
    const Tensor& x0 = xs[0];
    const int64_t d = detail::wrap_dim("concat", dim, x0.shape());
    int64_t total = 0;
    for (size_t i = 0; i < xs.size(); ++i) {
        const Tensor& x = xs[i];
        G2L_CHECK(x.dtype() == x0.dtype() && x.dim() == x0.dim(), "concat: tensor ", i, " ",
                  x.desc(), " does not match tensor 0 ", x0.desc(), " in dtype or rank");
        for (int64_t k = 0; k < x.dim(); ++k)
            G2L_CHECK(k == d || x.size(k) == x0.size(k), "concat: tensor ", i, " ", x.desc(),
                      " differs from tensor 0 ", x0.desc(), " in dim ", k, " (only dim ", d,
                      " may differ)");
        total += x.size(d);
    }
    Shape out_shape = x0.shape();
    out_shape[size_t(d)] = total;
    const detail::DimSplit p = detail::split_at(out_shape, d);
    Tensor y = Tensor::empty(out_shape, x0.dtype(), x0.device());
    std::vector<int64_t> offsets;
    int64_t off = 0;
    for (const Tensor& x : xs) {
        copy_slab(x, x.size(d), 0, y, total, off, p.outer, x.size(d), p.inner);
        offsets.push_back(off);
        off += x.size(d);
    }
    return autograd::record("concat", y, xs, [p, total, offsets, d, xs_shapes = [&] {
                                std::vector<Shape> s;
                                for (const Tensor& x : xs) s.push_back(x.shape());
                                return s;
                            }()](const Tensor& dy, autograd::Grads& g) {
        // The adjoint of concat: each input gets its own slab of dy back.
        for (size_t i = 0; i < xs_shapes.size(); ++i) {
            if (!g.needs(i)) continue;
            const int64_t len = xs_shapes[i][size_t(d)];
            Tensor dx = Tensor::empty(xs_shapes[i], dy.dtype(), dy.device());
            copy_slab(dy, total, offsets[i], dx, len, 0, p.outer, len, p.inner);
            g.add(i, dx);
        }
    });
}

Tensor stack(const std::vector<Tensor>& xs, int64_t dim) {
    G2L_CHECK(!xs.empty(), "stack: no tensors given");
    for (const Tensor& x : xs) check_input("stack", x);
    const int64_t d = wrap_insert_dim("stack", dim, xs[0].shape());
    std::vector<Tensor> parts;
    for (size_t i = 0; i < xs.size(); ++i) {
        G2L_CHECK(xs[i].shape() == xs[0].shape() && xs[i].dtype() == xs[0].dtype(),
                  "stack: tensor ", i, " ", xs[i].desc(), " differs from tensor 0 ", xs[0].desc(),
                  " (all must have the same shape and dtype)");
        parts.push_back(unsqueeze(xs[i], d));
    }
    return concat(parts, d);
}

Tensor slice(const Tensor& x, int64_t dim, int64_t start, int64_t end) {
    check_input("slice", x);
    const int64_t d = detail::wrap_dim("slice", dim, x.shape());
    const int64_t D = x.size(d);
    // Python slicing: negative indices count from the end and out-of-range bounds clamp, so an
    // empty slice is a result, not an error.
    auto clamp_index = [D](int64_t i) {
        if (i < 0) i += D;
        return std::min(std::max(i, int64_t(0)), D);
    };
    const int64_t s = clamp_index(start), len = std::max(clamp_index(end) - s, int64_t(0));
    Shape out_shape = x.shape();
    out_shape[size_t(d)] = len;
    const detail::DimSplit p = detail::split_at(x.shape(), d);
    Tensor y = Tensor::empty(out_shape, x.dtype(), x.device());
    copy_slab(x, D, s, y, len, 0, p.outer, len, p.inner);
    // Backward starts from zeros: rows outside the slice never reached the output.
    return autograd::record("slice", y, {x},
                            [p, s, len, xs = x.shape()](const Tensor& dy, autograd::Grads& g) {
                                Tensor dx = Tensor::zeros(xs, dy.dtype(), dy.device());
                                copy_slab(dy, len, 0, dx, p.D, s, p.outer, len, p.inner);
                                g.add(0, dx);
                            });
}

Tensor repeat(const Tensor& x, int64_t dim, int64_t n) {
    check_input("repeat", x);
    const int64_t d = detail::wrap_dim("repeat", dim, x.shape());
    G2L_CHECK(n >= 0, "repeat: count n must be >= 0, got ", n, " for ", x.desc());
    const detail::DimSplit p = detail::split_at(x.shape(), d);
    Shape out_shape = x.shape();
    out_shape[size_t(d)] = p.D * n;
    Tensor y = Tensor::empty(out_shape, x.dtype(), x.device());
    for (int64_t r = 0; r < n; ++r)
        copy_slab(x, p.D, 0, y, p.D * n, r * p.D, p.outer, p.D, p.inner);
    return autograd::record(
        "repeat", y, {x}, [p, n, xs = x.shape()](const Tensor& dy, autograd::Grads& g) {
            // dy viewed as [outer, n, D * inner]: the gradient is the sum over the tiles.
            Tensor dx = Tensor::empty(xs, dy.dtype(), dy.device());
            kernels::sum_dim(dy, dx, p.outer, n, p.D * p.inner);
            g.add(0, dx);
        });
}

Tensor transpose(const Tensor& x, int64_t d0, int64_t d1) {
    check_input("transpose", x);
    const int64_t a = detail::wrap_dim("transpose", d0, x.shape());
    const int64_t b = detail::wrap_dim("transpose", d1, x.shape());
    std::vector<int64_t> perm(static_cast<size_t>(x.dim()));
    for (size_t k = 0; k < perm.size(); ++k) perm[k] = int64_t(k);
    std::swap(perm[size_t(a)], perm[size_t(b)]);
    // Tensors are always dense (tensor.h), so a transpose is a permuted copy, not a view.
    return permute(x, perm);
}

Tensor permute(const Tensor& x, const std::vector<int64_t>& dims) {
    check_input("permute", x);
    const int64_t r = x.dim();
    G2L_CHECK(int64_t(dims.size()) == r, "permute: ", dims.size(), " dims given for ", x.desc());
    const size_t rr = static_cast<size_t>(r);
    std::vector<int64_t> perm(rr), inv(rr, -1);
    for (int64_t k = 0; k < r; ++k) {
        perm[size_t(k)] = detail::wrap_dim("permute", dims[size_t(k)], x.shape());
        G2L_CHECK(inv[size_t(perm[size_t(k)])] < 0, "permute: dim ", dims[size_t(k)],
                  " appears twice in the permutation for ", x.desc());
        inv[size_t(perm[size_t(k)])] = k;
    }
    const Tensor y = permute_raw(x, perm);
    // The adjoint of a permutation is the inverse permutation.
    return autograd::record("permute", y, {x}, [inv](const Tensor& dy, autograd::Grads& g) {
        g.add(0, permute_raw(dy, inv));
    });
}

Tensor index_select(const Tensor& x, int64_t dim, const Tensor& idx) {
    check_input("index_select", x);
    const int64_t d = detail::wrap_dim("index_select", dim, x.shape());
    G2L_CHECK(idx.defined(), "index_select: idx is undefined");
    G2L_CHECK(idx.dtype() == DType::I32 && idx.dim() == 1,
              "index_select: idx must be i32 [L], got ", idx.desc());
    const detail::DimSplit p = detail::split_at(x.shape(), d);
    const int64_t L = idx.numel();
    // The indices are checked on the host (a copy when idx lives on another device).
    const Tensor ih = idx.device().is_cpu() ? idx : idx.to(Device::cpu());
    const int32_t* pi = ih.data<int32_t>();
    // The kernels use the ids as raw offsets: an out-of-range id would read or write out of
    // bounds, so every id is checked here.
    for (int64_t l = 0; l < L; ++l)
        G2L_CHECK(pi[l] >= 0 && pi[l] < p.D, "index_select: idx[", l, "] = ", pi[l],
                  " is out of range [0, ", p.D, ") for dim ", dim, " of ", x.desc());
    Shape out_shape = x.shape();
    out_shape[size_t(d)] = L;
    Tensor y = Tensor::empty(out_shape, x.dtype(), x.device());
    kernels::index_select_fwd(x, idx, y, p.outer, p.D, p.inner);
    // idx is recorded as an input (it gets no gradient) so that an in-place change to it before
    // backward is caught by the version check.
    return autograd::record("index_select", y, {x, idx},
                            [p, L, idx, xs = x.shape()](const Tensor& dy, autograd::Grads& g) {
                                if (!g.needs(0)) return;
                                Tensor dx = Tensor::empty(xs, dy.dtype(), dy.device());
                                kernels::index_select_bwd(dy, idx, dx, p.outer, p.D, p.inner);
                                g.add(0, dx);
                            });
}

Tensor unsqueeze(const Tensor& x, int64_t dim) {
    check_input("unsqueeze", x);
    const int64_t d = wrap_insert_dim("unsqueeze", dim, x.shape());
    Shape s = x.shape();
    s.insert(s.begin() + d, 1);
    // A view: inserting or removing a size-1 dimension never moves data.
    return x.reshape(s);
}

Tensor squeeze(const Tensor& x, int64_t dim) {
    check_input("squeeze", x);
    const int64_t d = detail::wrap_dim("squeeze", dim, x.shape());
    G2L_CHECK(x.size(d) == 1, "squeeze: dim ", dim, " of ", x.desc(), " has size ", x.size(d),
              ", not 1");
    Shape s = x.shape();
    s.erase(s.begin() + d);
    return x.reshape(s);
}

}  // namespace g2l::nn
