// SPDX-License-Identifier: MIT
// MPI behind train/distributed.h; G2L_WITH_MPI is defined for this file only (train/CMakeLists).
#include "train/distributed.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstdio>
#include <thread>

#include "core/error.h"

#ifdef G2L_WITH_MPI
#include <mpi.h>
#endif

namespace g2l::train::dist {

#ifdef G2L_WITH_MPI

namespace {

bool g_started = false;  // MPI_Init_thread called by us
int g_local = 0;         // LocalScope depth: > 0 = MPI_COMM_SELF

bool running() {
    int init = 0, fin = 0;
    MPI_Initialized(&init);
    MPI_Finalized(&fin);
    return init && !fin;
}

MPI_Comm comm() { return g_local > 0 ? MPI_COMM_SELF : MPI_COMM_WORLD; }

void check(int rc, const char* call) {
    if (rc == MPI_SUCCESS) return;
    char text[MPI_MAX_ERROR_STRING];
    int len = 0;
    MPI_Error_string(rc, text, &len);
    G2L_CHECK(false, call, " failed: ", std::string(text, size_t(len)),
              " (a process of the job died or the network failed)");
}

}  // namespace

bool built_with_mpi() { return true; }

namespace {
// Started by an MPI launcher (mpirun / mpiexec / srun)? A plain `g2l_train` skips MPI_Init:
// a singleton init costs ~0.5 s and changes nothing for one process.
bool launched_by_mpi() {
    for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "PMI_RANK"})
        if (std::getenv(v)) return true;
    return false;
}
}  // namespace

void init(int* argc, char*** argv) {
    if (running() || !launched_by_mpi()) return;
    int provided = 0;
    check(MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
    g_started = true;
    // A dead peer must surface as an exception with a message, not as a silent abort.
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
}

void finalize() {
    if (g_started && running()) MPI_Finalize();
}

int abort_job(const std::string& why, int code) {
    if (!running() || size() == 1) return code;
    std::fprintf(stderr, "g2l_train (rank %d of %d): %s; stopping every rank of the job\n", rank(),
                 size(), why.c_str());
    std::fflush(stderr);
    MPI_Abort(MPI_COMM_WORLD, code);
    return code;
}

int rank() {
    if (!running()) return 0;
    int r = 0;
    MPI_Comm_rank(comm(), &r);
    return r;
}

int size() {
    if (!running()) return 1;
    int n = 1;
    MPI_Comm_size(comm(), &n);
    return n;
}

void allreduce_sum(float* values, int64_t n) {
    if (size() == 1 || n == 0) return;
    G2L_CHECK(n < (int64_t(1) << 31), "allreduce_sum: ", n, " values exceed MPI's int count");
    check(MPI_Allreduce(MPI_IN_PLACE, values, int(n), MPI_FLOAT, MPI_SUM, comm()),
          "MPI_Allreduce");
}

void allreduce_sum(double* values, int64_t n) {
    if (size() == 1 || n == 0) return;
    G2L_CHECK(n < (int64_t(1) << 31), "allreduce_sum: ", n, " values exceed MPI's int count");
    check(MPI_Allreduce(MPI_IN_PLACE, values, int(n), MPI_DOUBLE, MPI_SUM, comm()),
          "MPI_Allreduce");
}

void broadcast(void* data, int64_t bytes, int root) {
    if (size() == 1 || bytes == 0) return;
    G2L_CHECK(bytes < (int64_t(1) << 31), "broadcast: ", bytes, " bytes exceed MPI's int count");
    check(MPI_Bcast(data, int(bytes), MPI_BYTE, root, comm()), "MPI_Bcast");
}

void barrier() {
    if (size() == 1) return;
    MPI_Request req;
    check(MPI_Ibarrier(comm(), &req), "MPI_Ibarrier");
    int done = 0;
    for (;;) {
        check(MPI_Test(&req, &done, MPI_STATUS_IGNORE), "MPI_Test (barrier)");
        if (done) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
}

LocalScope::LocalScope() { ++g_local; }
LocalScope::~LocalScope() { --g_local; }

#else  // no MPI: one process

bool built_with_mpi() { return false; }
void init(int*, char***) {}
void finalize() {}
int abort_job(const std::string&, int code) { return code; }
int rank() { return 0; }
int size() { return 1; }
void allreduce_sum(float*, int64_t) {}
void allreduce_sum(double*, int64_t) {}
void broadcast(void*, int64_t, int) {}
void barrier() {}
LocalScope::LocalScope() {}
LocalScope::~LocalScope() {}

#endif

void allreduce_average(float* values, int64_t n) {
    allreduce_sum(values, n);
    const int s = size();
    if (s > 1)
        for (int64_t i = 0; i < n; ++i) values[i] /= float(s);
}

double allreduce_gradients(const nn::Adam& adam, std::vector<float>& extra) {
    if (size() == 1) return 0;
    std::vector<Tensor> grads;
    int64_t n = 0;
    for (const nn::ParamGroup& g : adam.groups())
        for (const auto& [name, p] : g.params) {
            const Tensor gr = p.grad();
            if (!gr.defined()) continue;
            G2L_CHECK(gr.dtype() == DType::F32, "allreduce_gradients: the gradient of '", name,
                      "' is ", gr.desc(), "; data-parallel training sums F32 gradients");
            grads.push_back(gr);
            n += gr.numel();
        }
    std::vector<float> buf(size_t(n) + extra.size());
    int64_t at = 0;
    for (const Tensor& g : grads) {
        std::copy_n(g.data<float>(), g.numel(), buf.begin() + at);
        at += g.numel();
    }
    std::copy(extra.begin(), extra.end(), buf.begin() + at);
    const auto t0 = std::chrono::steady_clock::now();
    allreduce_sum(buf.data(), int64_t(buf.size()));
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    at = 0;
    for (Tensor& g : grads) {
        // Tensors alias their storage: this writes the parameter's gradient in place.
        std::copy_n(buf.begin() + at, g.numel(), g.data<float>());
        at += g.numel();
    }
    std::copy(buf.begin() + at, buf.end(), extra.begin());
    return s;
}

std::pair<int64_t, int64_t> shard(int64_t global) {
    const int64_t n = size(), r = rank();
    G2L_CHECK(global >= n, "train.batch ", global, " is smaller than the ", n,
              " processes of the job: every process needs at least one sample per step");
    // first(r) = r * q + min(r, rem): the first `rem` ranks hold q + 1 samples.
    const int64_t q = global / n, rem = global % n;
    const int64_t first = r * q + std::min(r, rem);
    return {first, first + q + (r < rem ? 1 : 0)};
}

nn::DataParallel step_hook(int64_t global, int64_t offset) {
    nn::DataParallel dp;
    dp.global_batch = global;
    dp.batch_offset = offset;
    if (size() > 1) dp.sum = [](double* v, int64_t n) { allreduce_sum(v, n); };
    return dp;
}

}  // namespace g2l::train::dist
