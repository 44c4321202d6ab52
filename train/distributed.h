// SPDX-License-Identifier: MIT
// Data-parallel training over processes (MPI; docs/distributed.md). The ONLY place that talks to
// MPI: both trainers and g2l_train use these calls, and without MPI (G2L_MPI=OFF, or a program
// not started by mpirun) they describe one process of a world of one, and every collective is
// a no-op. infer/ and the layers below never depend on it: BatchNorm and dropout see the split
// batch through nn/data_parallel.h, which dist::step_hook fills.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "nn/data_parallel.h"
#include "nn/optim.h"

namespace g2l::train::dist {

/// True when this build has MPI (CMake G2L_MPI).
bool built_with_mpi();

/// Starts MPI when the build has it and an MPI launcher started this process (mpirun, mpiexec,
/// srun: their environment variables), with MPI_Init_thread FUNNELED (only the calling thread
/// talks to MPI; the trainers' prefetch threads never do). Call once, first thing in main; a
/// second call does nothing. Errors on the communicator return (MPI_ERRORS_RETURN) and throw g2l::Error
/// naming the call, so main can report and abort the job.
void init(int* argc, char*** argv);
/// Ends MPI (once, at the end of main; a no-op when init did not start it).
void finalize();
/// Ends every process of the job at once (MPI_Abort) after printing `why` (rank-prefixed) on
/// stderr; without MPI or with one process it only returns `code` for main to return.
int abort_job(const std::string& why, int code);

/// This process's rank and the number of processes (0 and 1 without MPI).
int rank();
int size();
/// True on rank 0, the process that writes logs, config.json and checkpoints.
inline bool is_root() { return rank() == 0; }

/// [first, end) of this process's share of a global batch of `global` samples: contiguous
/// slices, the first `global % size()` processes one sample larger. Throws when global < size()
/// (a process without a sample), naming both.
std::pair<int64_t, int64_t> shard(int64_t global);

/// Sums n floats / doubles over all processes, in place (MPI_Allreduce, MPI_SUM). Every process
/// must call it with the same n, in the same order. Throws g2l::Error on an MPI failure.
void allreduce_sum(float* values, int64_t n);
void allreduce_sum(double* values, int64_t n);
/// The step's ONE gradient all-reduce: the gradients of every parameter of `adam` that has one
/// (F32; the same set on every process, as the graph is the same) and then `extra` (the step's
/// weighted loss terms and stop flags) packed into one flat float buffer, summed over the
/// processes (one MPI_Allreduce of (parameters + extra.size()) x 4 bytes) and written back.
/// Each process must have scaled its loss by its share of the global batch, so the sum is the
/// one-process gradient of the global batch's mean loss. Returns the seconds the all-reduce
/// took (0 with one process, which changes nothing).
double allreduce_gradients(const nn::Adam& adam, std::vector<float>& extra);

/// Averages n floats over all processes, in place (sum / size()).
void allreduce_average(float* values, int64_t n);
/// Copies `bytes` bytes of `data` from `root` to every other process.
void broadcast(void* data, int64_t bytes, int root = 0);
/// Waits until every process reaches it. The waiting processes sleep (1 ms polls) instead of
/// spinning, so a rank that validates alone keeps the cores.
void barrier();

/// The engine hook of one training step whose global batch has `global` samples, this process
/// holding [offset, offset + local): BatchNorm sums its statistics through allreduce_sum,
/// dropout keeps its rows of the global mask. Null `sum` when size() == 1 (nothing to share).
nn::DataParallel step_hook(int64_t global, int64_t offset);

/// While alive, the collectives run over this process alone (MPI_COMM_SELF): rank 0, size 1.
/// For tests that compare a one-process run with the job's (tests/train/test_distributed_mpi).
class LocalScope {
public:
    LocalScope();
    ~LocalScope();
    LocalScope(const LocalScope&) = delete;
    LocalScope& operator=(const LocalScope&) = delete;
};

}  // namespace g2l::train::dist
