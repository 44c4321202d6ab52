#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""LibTorch baseline for g2l_bench's `train_samples_per_s` / `train_step_ms`.

A PyTorch re-implementation of the one G2L-Net training step that
tools/bench.cpp `bench_training()` times, so that our engine and LibTorch can be
compared on the same machine in one sitting. What it mirrors:

* Data (bench_training): `--batch` (8) random crops of `--points` (1500) points in mm;
  even points are the object (label 1, uniform in a 100 mm cube), odd ones the
  background (uniform in a 300 mm cube); class index b % 16; 16 classes; K = 8 box
  keypoints (+-40, +-30, +-50 mm); GT pose R = I, t = 0 (PoseSample's defaults).
* Network (nn/models/g2l_net.*, g2l_blocks.*; spec ../shared/docs/g2l_spec.md §4),
  G2LConfig defaults: width 1 (paper widths), evf and rre on, class_heads off,
  dropout 0.2 (block C input 0.3), rot_unit "mm", out_scale_mm 1. Every 1x1 conv is
  an nn.Conv1d(kernel_size=1) (or a matmul with --conv matmul) followed by
  BatchNorm1d (+ ReLU), max-pooling over the points, one-hot concatenated after the
  backbone / after the T-net's max-pool:
    seg   backbone 3-64-64-64-128-1024 (no ReLU after conv5), head on
          [x1, x2, pf | g, onehot] 2256-512-256-128-128, Dropout, 128->2, log_softmax
    tnet  3-128-256-512 (no ReLU last), max, +onehot 528-256-128 (no ReLU last),
          Dropout, 128->3 (the official unused conv4 is not built, as in ours)
    evf   (block A) own backbone + head as seg, Dropout, 128->24 unit-vector field
    rot   (block B) [vectors(24), detached x1, x2, pf | g, onehot] 2280-1024-512-256,
          max, fc 256-256-128-128 (BN + ReLU), Dropout, 128->24 keypoints
    rre   (block C) Dropout(0.3) on the detached features, 2256-256-128 (no ReLU
          last), max, 128->24 residual
  A head's first layer runs like our concat_conv1x1: one conv over the concatenated
  per-point features plus one Linear over the global [g, onehot] per cloud,
  broadcast over the points (the tiled [B, 2256, N] tensor is never built); in
  block B A's vectors get a conv of their own so that backward computes the input
  gradient of those 24 channels only (the detached features need none). Same
  FLOPs and the same parameter count as ours (7,049,165 at width 1, 16 classes, K 8).
* Step (train/pipeline.cpp g2l_step, LossWeights defaults): seg on the 1500-point
  crop (NLL, weight 10); `--seg-points` (1000) points drawn with replacement among
  those predicted object (the GT object points if fewer than 10); T-net on them minus
  their mean (MSE, 0.1); blocks A/B/C on the drawn points minus the GT translation:
  MSE of A's vectors against unit vectors to the keypoints, zero for background
  points (10), B's keypoints (0.01), C: batched Kabsch (detached) of the model
  keypoints onto B's keypoints + C's residual against the GT keypoints (0.01).
  Then backward() and Adam (lr 1e-3, betas (0.9, 0.999), eps 1e-8, our AdamOptions
  defaults) with the per-network lr multipliers of G2LNet::param_groups (seg 1,
  tnet 10, evf 1, rot 30, rre 20); zero_grad sets the grads to None as ours does.
* Timing (median_seconds(..., reps, 1)): one warm-up step, then the median of
  `--reps` steps; train_samples_per_s = batch / median.

Run (Debian's python3-torch lives in /usr/bin/python3; a pyenv `python3` without
torch re-executes this script under /usr/bin/python3):

    /usr/bin/python3 tools/torch_bench.py --threads 2 --reps 5 --json

next to (g2l_bench has no --train-only; these flags skip every other figure except
the fixed engine/GEMM ones, which --reps 1 keeps short):

    build/apps/g2l_bench --threads 2 --train-reps 5 --reps 1 --pose-reps 0 \
        --detector-reps 0 --refine-reps 0 --frame-reps 0 --json

and compare the two train_samples_per_s / train_step_ms (do not use g2l_bench
--quick: it shrinks the training figure to batch 2, 300 -> 200 points).

BLAS: Debian's torch calls whatever libblas.so.3 the system points at (the `blas`
field says which). With 2+ threads its 1x1 convolutions run on oneDNN, so the BLAS
hardly matters (measured 2026-12-04: reference BLAS 1.41, OpenBLAS 1.28-1.29
samples/s in the same sitting); at 1 thread they fall back to a BLAS path, and
the reference BLAS is then the bottleneck: install libopenblas0-pthread and run
with LD_LIBRARY_PATH=/usr/lib/x86_64-linux-gnu/openblas-pthread (no system-wide
switch needed).

Caveat: Debian builds torch with BLAS_INFO=generic, i.e. it calls whatever
libblas.so.3 the alternatives system points at (the "blas" field says which one).
With only libblas3 (netlib reference BLAS) installed, every matmul-backed op
(Linear, --conv matmul, and Conv1d when oneDNN is not chosen) runs unoptimised;
`apt-get install libopenblas0-pthread` switches it. LibTorch 1.13 sends a 1x1
Conv1d to oneDNN (mkldnn_convolution) only when more than one thread is set or
the batch is >= 16; at --threads 1 with batch 8 it takes THNN (_slow_conv2d, a
BLAS GEMM), which with reference BLAS is many times slower. `--conv mkldnn`
forces oneDNN at any thread count; `--profile` lists the aten ops of one step.
"""

import argparse
import json
import math
import os
import sys
import time


def _threads_from_argv(argv):
    for i, a in enumerate(argv):
        if a == "--threads" and i + 1 < len(argv):
            return argv[i + 1]
        if a.startswith("--threads="):
            return a.split("=", 1)[1]
    return "2"


# torch.set_num_threads sizes LibTorch's own pool but not OpenBLAS's, which is sized from the
# environment when the library loads (default: every core). Without this, "--threads 1" ran its
# BLAS convolutions on 2 threads (the 2026-12-04 afternoon figure, 3.55 samples/s; 2.69 with one).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_var, _threads_from_argv(sys.argv))

try:
    import torch
    import torch.nn as nn
    import torch.nn.functional as F
except ImportError:  # pyenv / venv python without Debian's python3-torch
    if os.path.exists("/usr/bin/python3") and \
            os.path.realpath(sys.executable) != os.path.realpath("/usr/bin/python3"):
        os.execv("/usr/bin/python3", ["/usr/bin/python3"] + sys.argv)
    raise

NUM_CLASSES = 16
NUM_KEYPOINTS = 8
CONV_MODE = "conv1d"  # set from --conv before the model is built


def scaled_width(base, width):
    """max(8, llround(base * width)), as nn::scaled_width."""
    return max(8, int(math.floor(base * width + 0.5)))


class PointConv(nn.Module):
    """1x1 convolution over [B, Cin, N] -> [B, Cout, N] (our Conv1x1)."""

    def __init__(self, cin, cout):
        super().__init__()
        self.conv = nn.Conv1d(cin, cout, kernel_size=1)

    def forward(self, x):
        if CONV_MODE == "matmul":
            w = self.conv.weight.squeeze(2)
            y = torch.matmul(w, x)
            return y if self.conv.bias is None else y + self.conv.bias[:, None]
        if CONV_MODE == "mkldnn":  # oneDNN whatever the thread count / batch
            return torch.mkldnn_convolution(x, self.conv.weight, self.conv.bias, [0], [1], [1], 1)
        return self.conv(x)


class SharedMlp(nn.Module):
    """conv-BN(-ReLU) stack over [B, C, N]; returns every layer's output (taps)."""

    def __init__(self, widths, relu_last):
        super().__init__()
        self.convs = nn.ModuleList(PointConv(a, b) for a, b in zip(widths[:-1], widths[1:]))
        self.bns = nn.ModuleList(nn.BatchNorm1d(b) for b in widths[1:])
        self.relu_last = relu_last

    def forward(self, x):
        taps = []
        n = len(self.convs)
        for i, (conv, bn) in enumerate(zip(self.convs, self.bns)):
            x = bn(conv(x))
            if i + 1 < n or self.relu_last:
                x = F.relu(x)
            taps.append(x)
        return taps


class Mlp(nn.Module):
    """Linear-BN(-ReLU) stack over [B, C] rows."""

    def __init__(self, widths, relu_last):
        super().__init__()
        self.fcs = nn.ModuleList(nn.Linear(a, b) for a, b in zip(widths[:-1], widths[1:]))
        self.bns = nn.ModuleList(nn.BatchNorm1d(b) for b in widths[1:])
        self.relu_last = relu_last

    def forward(self, x):
        n = len(self.fcs)
        for i, (fc, bn) in enumerate(zip(self.fcs, self.bns)):
            x = bn(fc(x))
            if i + 1 < n or self.relu_last:
                x = F.relu(x)
        return x


class Backbone(nn.Module):
    """PointNet backbone (spec §4.1) -> per-point taps x1, x2, pf and global g."""

    def __init__(self, w):
        super().__init__()
        self.c1, self.c2, self.c5 = scaled_width(64, w), scaled_width(128, w), scaled_width(1024, w)
        self.mlp = SharedMlp([3, scaled_width(64, w), scaled_width(64, w), scaled_width(64, w),
                              self.c2, self.c5], relu_last=False)

    def forward(self, x):
        t = self.mlp(x)
        pf = t[4]
        return {"x1": t[1], "x2": t[3], "pf": pf, "g": pf.max(dim=2).values}


class ConcatMlp(nn.Module):
    """Head whose first layer sees [per-point features | global features] (our ConcatMlp on
    concat_conv1x1): a conv over the concatenated per-point features plus a Linear (no bias)
    over the concatenated global vectors, added once per cloud; then conv-BN(-ReLU) layers.
    `point_groups` (channel counts summing to in_point) splits the per-point part into convs
    of their own: block B keeps A's live vectors apart from the detached features, so that
    backward computes the input gradient of the 24 vector channels only (as ours) rather than
    of all 1240 concatenated ones."""

    def __init__(self, in_point, in_global, hidden, relu_last, point_groups=None):
        super().__init__()
        groups = point_groups or [in_point]
        assert sum(groups) == in_point
        self.groups = groups
        self.conv1 = PointConv(groups[0], hidden[0])
        self.conv1_more = nn.ModuleList(PointConv(c, hidden[0]) for c in groups[1:])
        for m in self.conv1_more:  # one bias for the layer, as ours
            m.conv.bias = None
        self.conv1_global = nn.Linear(in_global, hidden[0], bias=False)
        self.bn1 = nn.BatchNorm1d(hidden[0])
        self.rest = SharedMlp(hidden, relu_last) if len(hidden) > 1 else None
        self.relu_first = len(hidden) > 1 or relu_last

    def forward(self, point, glob):
        parts, i = [], 0
        for c in self.groups:  # consecutive tensors of `point` make up each group
            grp, n = [], 0
            while n < c:
                grp.append(point[i])
                n += point[i].shape[1]
                i += 1
            parts.append(grp[0] if len(grp) == 1 else torch.cat(grp, 1))
        g = glob[0] if len(glob) == 1 else torch.cat(glob, 1)
        h = self.conv1(parts[0])
        for conv, p in zip(self.conv1_more, parts[1:]):
            h = h + conv(p)
        h = self.bn1(h + self.conv1_global(g)[:, :, None])
        if self.relu_first:
            h = F.relu(h)
        return self.rest(h)[-1] if self.rest is not None else h


def seg_head(w):
    return [scaled_width(512, w), scaled_width(256, w), scaled_width(128, w), scaled_width(128, w)]


class SegNet(nn.Module):
    def __init__(self, w, C, p):
        super().__init__()
        self.backbone = Backbone(w)
        b = self.backbone
        self.head = ConcatMlp(b.c1 + b.c2 + b.c5, b.c5 + C, seg_head(w), relu_last=True)
        self.drop = nn.Dropout(p)
        self.out = PointConv(seg_head(w)[-1], 2)

    def forward(self, x, onehot):
        f = self.backbone(x)
        h = self.drop(self.head([f["x1"], f["x2"], f["pf"]], [f["g"], onehot]))
        return F.log_softmax(self.out(h), dim=1)


class TNet(nn.Module):
    def __init__(self, w, C, p):
        super().__init__()
        c3 = scaled_width(512, w)
        self.mlp = SharedMlp([3, scaled_width(128, w), scaled_width(256, w), c3], relu_last=False)
        self.fc = Mlp([c3 + C, scaled_width(256, w), scaled_width(128, w)], relu_last=False)
        self.drop = nn.Dropout(p)
        self.out = nn.Linear(scaled_width(128, w), 3)

    def forward(self, x, onehot):
        g = self.mlp(x)[-1].max(dim=2).values
        return self.out(self.drop(self.fc(torch.cat([g, onehot], 1))))


class EvfNet(nn.Module):
    """Block A: per-point vectors [B, 3K, N] and the DETACHED features for blocks B and C."""

    def __init__(self, w, C, K, p):
        super().__init__()
        self.backbone = Backbone(w)
        b = self.backbone
        self.head = ConcatMlp(b.c1 + b.c2 + b.c5, b.c5 + C, seg_head(w), relu_last=True)
        self.drop = nn.Dropout(p)
        self.out = PointConv(seg_head(w)[-1], 3 * K)

    def forward(self, x, onehot):
        f = self.backbone(x)
        h = self.drop(self.head([f["x1"], f["x2"], f["pf"]], [f["g"], onehot]))
        feat = {k: v.detach() for k, v in f.items()}
        feat["onehot"] = onehot
        return self.out(h), feat


class RotNet(nn.Module):
    """Block B on [A's vectors (live), detached features] -> keypoints [B, K, 3]."""

    def __init__(self, w, C, K, p):
        super().__init__()
        self.K = K
        c1, c2, c5 = scaled_width(64, w), scaled_width(128, w), scaled_width(1024, w)
        self.mlp = ConcatMlp(3 * K + c1 + c2 + c5, c5 + C,
                             [scaled_width(1024, w), scaled_width(512, w), scaled_width(256, w)],
                             relu_last=True, point_groups=[3 * K, c1 + c2 + c5])
        self.fc = Mlp([scaled_width(256, w), scaled_width(256, w), scaled_width(128, w),
                       scaled_width(128, w)], relu_last=True)
        self.drop = nn.Dropout(p)
        self.out = nn.Linear(scaled_width(128, w), 3 * K)

    def forward(self, vectors, feat):
        g = self.mlp([vectors, feat["x1"], feat["x2"], feat["pf"]],
                     [feat["g"], feat["onehot"]]).max(dim=2).values
        kp = self.out(self.drop(self.fc(g)))
        return kp.reshape(kp.shape[0], self.K, 3)


class RreNet(nn.Module):
    """Block C: Dropout(0.3) on every input tensor (per-point ones element-wise, the global
    [B, C] ones per (sample, channel), as ours) -> residual [B, K, 3]."""

    def __init__(self, w, C, K, p_in):
        super().__init__()
        self.K = K
        c1, c2, c5 = scaled_width(64, w), scaled_width(128, w), scaled_width(1024, w)
        self.drop = nn.Dropout(p_in)
        self.mlp = ConcatMlp(c1 + c2 + c5, c5 + C, [scaled_width(256, w), scaled_width(128, w)],
                             relu_last=False)
        self.out = nn.Linear(scaled_width(128, w), 3 * K)

    def forward(self, feat):
        point = [self.drop(feat[k]) for k in ("x1", "x2", "pf")]
        glob = [self.drop(feat[k]) for k in ("g", "onehot")]
        r = self.out(self.mlp(point, glob).max(dim=2).values)
        return r.reshape(r.shape[0], self.K, 3)


class G2LNet(nn.Module):
    def __init__(self, width=1.0, C=NUM_CLASSES, K=NUM_KEYPOINTS, p=0.2, p_rre=0.3):
        super().__init__()
        self.seg = SegNet(width, C, p)
        self.tnet = TNet(width, C, p)
        self.evf = EvfNet(width, C, K, p)
        self.rot = RotNet(width, C, K, p)
        self.rre = RreNet(width, C, K, p_rre)

    def param_groups(self, lr):
        mult = {"seg": 1, "tnet": 10, "evf": 1, "rot": 30, "rre": 20}  # G2LLrMults
        return [{"params": list(getattr(self, n).parameters()), "lr": lr * m}
                for n, m in mult.items()]


def kabsch_batched(P, Q):
    """R [B, 3, 3] mapping centred P [B, K, 3] onto centred Q (float64, as ours)."""
    Pc = P - P.mean(1, keepdim=True)
    Qc = Q - Q.mean(1, keepdim=True)
    H = Pc.transpose(1, 2) @ Qc
    U, _, Vh = torch.linalg.svd(H)
    V = Vh.transpose(1, 2)
    d = torch.sign(torch.det(V @ U.transpose(1, 2)))
    D = torch.diag_embed(torch.stack([torch.ones_like(d), torch.ones_like(d), d], 1))
    return V @ D @ U.transpose(1, 2)


def g2l_step(net, x, labels, onehot, cls, R, t, kp_table, M):
    """train/pipeline.cpp g2l_step with LossWeights{} and StepOptions{}: returns the total."""
    B, _, N = x.shape
    K = kp_table.shape[1]
    # 1. segmentation on the crop
    logp = net.seg(x, onehot)                          # [B, 2, N]
    l_seg = F.nll_loss(logp, labels)
    # 2. M points drawn with replacement among the predicted object points (GT object points
    #    when fewer than 10 are predicted, all points when there are none)
    with torch.no_grad():
        pred = logp[:, 1, :] > logp[:, 0, :]
        gt = labels.bool()
        use_pred = pred.sum(1, keepdim=True) >= 10
        wts = torch.where(use_pred, pred, gt).float()
        wts[wts.sum(1) == 0] = 1.0
        pick = torch.multinomial(wts, M, replacement=True)          # [B, M]
        pts = x.gather(2, pick[:, None, :].expand(B, 3, M))        # [B, 3, M]
        mean = pts.mean(2)                                          # [B, 3]
        xt = pts - mean[:, :, None]
        t_target = t - mean
    # 3. translation residual
    t_pred = net.tnet(xt, onehot)
    l_t = F.mse_loss(t_pred, t_target)
    # 4. rotation blocks in the canonical frame (centre = GT translation, no noise)
    with torch.no_grad():
        centre = t
        xr = pts - centre[:, :, None]
        obj = labels.gather(1, pick).bool()                         # [B, M]
    vectors, feat = net.evf(xr, onehot)
    kp = net.rot(vectors, feat)                                     # [B, K, 3]
    res = net.rre(feat)
    with torch.no_grad():
        kp_model = kp_table[cls]                                    # [B, K, 3]
        kpc = kp_model @ R.transpose(1, 2) + (t - centre)[:, None, :]
        v = kpc[:, :, :, None] - xr[:, None, :, :]                  # [B, K, 3, M]
        n = v.norm(dim=2, keepdim=True)
        v = torch.where(n > 1e-6, v / n, v) * obj[:, None, None, :]
        vec_target = v.reshape(B, 3 * K, M)
        Rh = kabsch_batched(kp_model.double(), kp.detach().double())
        th = kp.detach().double().mean(1) - (Rh @ kp_model.double().mean(1)[:, :, None])[:, :, 0]
        base = (kp_model.double() @ Rh.transpose(1, 2) + th[:, None, :]).float()
    l_vec = F.mse_loss(vectors, vec_target)
    l_kp = F.mse_loss(kp, kpc)
    l_res = F.mse_loss(base + res, kpc)
    return 10 * l_seg + 0.1 * l_t + 10 * l_vec + 0.01 * l_kp + 0.01 * l_res


def make_batch(B, N, C, K, gen):
    """bench_training's random crops and keypoint table."""
    obj = (torch.arange(N) % 2 == 0)
    half = torch.where(obj, torch.tensor(50.0), torch.tensor(150.0))
    x = ((torch.rand(B, 3, N, generator=gen) * 2 - 1) * half).contiguous()
    labels = obj.long().expand(B, N).contiguous()
    cls = torch.arange(B) % C
    onehot = F.one_hot(cls, C).float()
    kp = torch.tensor([[40.0 if i & 1 else -40.0, 30.0 if i & 2 else -30.0,
                        50.0 if i & 4 else -50.0] for i in range(K)])
    kp_table = kp.expand(C, K, 3).contiguous()
    R = torch.eye(3).expand(B, 3, 3).contiguous()
    t = torch.zeros(B, 3)
    return x, labels, onehot, cls, R, t, kp_table


def blas_library():
    """The libblas / BLAS-like shared objects this process mapped (resolved)."""
    libs = set()
    try:
        with open("/proc/self/maps") as f:
            for line in f:
                path = line.split()[-1] if "/" in line else ""
                name = os.path.basename(path).lower()
                if any(k in name for k in ("blas", "mkl_rt", "libmkl", "blis")):
                    libs.add(os.path.realpath(path))
    except OSError:
        pass
    return ",".join(sorted(libs)) or "unknown"


def main():
    global CONV_MODE
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--threads", type=int, default=2, help="torch.set_num_threads")
    ap.add_argument("--reps", type=int, default=5, help="timed steps after 1 warm-up (median)")
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--points", type=int, default=1500, help="points per crop (seg net)")
    ap.add_argument("--seg-points", type=int, default=1000, help="points for T-net and A/B/C")
    ap.add_argument("--width", type=float, default=1.0, help="width multiplier (g2l_bench --width)")
    ap.add_argument("--conv", choices=("conv1d", "mkldnn", "matmul"), default="conv1d",
                    help="1x1 convs as nn.Conv1d (LibTorch picks oneDNN or THNN+BLAS), forced "
                         "oneDNN (torch.mkldnn_convolution) or a batched matmul (BLAS)")
    ap.add_argument("--foreach", action="store_true", help="torch.optim.Adam(foreach=True)")
    ap.add_argument("--profile", action="store_true",
                    help="also print the 20 costliest aten ops of one step")
    ap.add_argument("--layers", action="store_true",
                    help="print every parameter's name and shape, then exit (no step)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    a = ap.parse_args()
    if min(a.threads, a.reps, a.batch, a.points, a.seg_points) < 1 or a.width <= 0:
        ap.error("threads, reps, batch, points and seg-points must be >= 1, width > 0")
    CONV_MODE = a.conv
    torch.set_num_threads(a.threads)
    torch.manual_seed(1)

    net = G2LNet(a.width).train()
    params = sum(p.numel() for p in net.parameters())
    if a.layers:
        for n, p in net.named_parameters():
            print("%-36s %s" % (n, list(p.shape)))
        print("total %d" % params)
        return
    opt = torch.optim.Adam(net.param_groups(1e-3), lr=1e-3, betas=(0.9, 0.999), eps=1e-8,
                           weight_decay=0.0, foreach=a.foreach or None)
    gen = torch.Generator().manual_seed(5)
    batch = make_batch(a.batch, a.points, NUM_CLASSES, NUM_KEYPOINTS, gen)

    def step():
        opt.zero_grad(set_to_none=True)
        loss = g2l_step(net, *batch, a.seg_points)
        loss.backward()
        opt.step()
        return loss

    loss0 = step()  # warm-up (median_seconds(..., reps, 1))
    if not torch.isfinite(loss0):
        sys.exit("torch_bench: non-finite loss %s" % loss0.item())
    times = []
    for _ in range(a.reps):
        t0 = time.perf_counter()
        step()
        times.append(time.perf_counter() - t0)
    med = sorted(times)[len(times) // 2]

    if a.profile:
        with torch.autograd.profiler.profile() as prof:
            step()
        print(prof.key_averages().table(sort_by="self_cpu_time_total", row_limit=20))

    out = {
        "torch": torch.__version__,
        "threads": torch.get_num_threads(),
        "train_samples_per_s": a.batch / med,
        "train_step_ms": med * 1e3,
        "params": params,
        "batch": a.batch, "points": a.points, "seg_points": a.seg_points, "width": a.width,
        "reps": a.reps, "conv": a.conv, "mkldnn": torch.backends.mkldnn.is_available(),
        "blas": blas_library(),
    }
    if a.json:
        print(json.dumps(out))
        return
    what = "G2L-Net step (width %g, batch %d, %d -> %d points)" % (
        a.width, a.batch, a.points, a.seg_points)
    print("torch_bench (torch %s, %d threads, median of %d, conv %s, blas %s)" % (
        out["torch"], out["threads"], a.reps, a.conv, out["blas"]))
    print("  %-28s %10.2f %-9s  %s" % ("train_samples_per_s", out["train_samples_per_s"],
                                        "samples/s", what))
    print("  %-28s %10.2f %-9s  %s" % ("train_step_ms", out["train_step_ms"], "ms", what))
    print("  %-28s %10d %-9s  %s" % ("params", params, "", "trainable parameters (" + ", ".join(
        "%s %d" % (n, sum(p.numel() for p in m.parameters())) for n, m in net.named_children()) + ")"))
    print("  first-step loss %.4f" % loss0.item())


if __name__ == "__main__":
    main()
