// SPDX-License-Identifier: MIT
#include "gradcheck.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/autograd.h"
#include "core/rng.h"

namespace g2l::testing {

namespace {
double weighted_sum(const Tensor& y, const Tensor& r) {
    const Tensor yc = y.to(Device::cpu()).to(DType::F64);
    const double* a = yc.data<double>();
    const double* b = r.data<double>();
    double s = 0;
    for (int64_t i = 0; i < yc.numel(); ++i) s += a[i] * b[i];
    return s;
}
}  // namespace

void gradcheck(const TensorFn& f, const std::vector<Tensor>& inputs, const GradcheckOptions& opt) {
    Rng rng(opt.seed);
    for (const Tensor& x : inputs) {
        G2L_CHECK(x.dtype() == DType::F64 || !x.requires_grad(),
                  "gradcheck: inputs that require grad must be f64, got ", x.desc());
        if (x.requires_grad()) const_cast<Tensor&>(x).zero_grad();
    }
    const Tensor y = f(inputs);
    G2L_CHECK(y.requires_grad(), "gradcheck: output does not require grad");
    const Tensor r = Tensor::randn(y.shape(), rng, DType::F64);
    y.backward(r.to(y.dtype()));

    for (size_t k = 0; k < inputs.size(); ++k) {
        Tensor x = inputs[k];
        if (!x.requires_grad()) continue;
        const Tensor analytic = x.grad();
        G2L_CHECK(analytic.defined(), "gradcheck: input ", k, " ", x.desc(),
                  " received no gradient");
        std::vector<int64_t> idx(size_t(x.numel()));
        std::iota(idx.begin(), idx.end(), 0);
        if (x.numel() > opt.max_checked) {
            for (int i = 0; i < opt.sampled; ++i)
                std::swap(idx[size_t(i)], idx[size_t(i) + rng.below(idx.size() - size_t(i))]);
            idx.resize(size_t(opt.sampled));
        }
        double* px = x.data<double>();
        const double* pa = analytic.data<double>();
        autograd::NoGradGuard no_grad;
        for (int64_t i : idx) {
            const double orig = px[i];
            px[i] = orig + opt.eps;
            const double lp = weighted_sum(f(inputs), r);
            px[i] = orig - opt.eps;
            const double lm = weighted_sum(f(inputs), r);
            px[i] = orig;
            const double numeric = (lp - lm) / (2 * opt.eps);
            const double a = pa[i];
            const double tol = opt.atol + opt.rtol * std::max(std::fabs(a), std::fabs(numeric));
            G2L_CHECK(std::fabs(a - numeric) <= tol, "gradcheck: input ", k, " ", x.desc(),
                      " flat index ", i, ": analytic ", a, " vs numeric ", numeric,
                      " (|diff| ", std::fabs(a - numeric), " > tol ", tol, ")");
        }
    }
}

Tensor distinct_values(const Shape& shape, uint64_t seed, double min_gap) {
    const int64_t n = shape_numel(shape);
    std::vector<double> v(static_cast<size_t>(n));
    for (int64_t i = 0; i < n; ++i) v[size_t(i)] = (double(i) - double(n) / 2 + 0.5) * min_gap * 1.5;  // never exactly 0
    Rng rng(seed);
    for (int64_t i = n - 1; i > 0; --i) std::swap(v[size_t(i)], v[rng.below(uint64_t(i) + 1)]);
    return Tensor::from_vector(v, shape);
}

double max_abs_diff(const Tensor& a, const Tensor& b) {
    G2L_CHECK(a.shape() == b.shape(), "max_abs_diff: shapes ", a.desc(), " vs ", b.desc());
    const Tensor x = a.to(Device::cpu()).to(DType::F64), y = b.to(Device::cpu()).to(DType::F64);
    double m = 0;
    for (int64_t i = 0; i < x.numel(); ++i)
        m = std::max(m, std::fabs(x.data<double>()[i] - y.data<double>()[i]));
    return m;
}

}  // namespace g2l::testing
