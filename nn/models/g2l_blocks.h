// SPDX-License-Identifier: MIT
// The G2L-Net sub-networks (spec §4; official code utils/networks_arch.py). All point inputs are
// batch-first and channel-first: x [B, 3, N] in mm; the class is a one-hot [B, num_classes].
//
// Head input channel order. The official heads see concat[x1, x2, g (tiled), pf, onehot]
// (64 + 128 + 1024 + 1024 + 16 = 2256 at width 1). Our first head layer runs concat_conv1x1 with
// the per-point tensors first and the global vectors after, so its weight columns are ordered
// [x1, x2, pf, g, onehot]. Importing an official conv1 weight W_off [Cout, 2256] therefore means
// moving column blocks: ours = W_off[:, 0:192] | W_off[:, 1216:2240] | W_off[:, 192:1216] |
// W_off[:, 2240:2256] (see official_head_columns()). Block B's input is prefixed by the 3K
// vectors of block A in both orders.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "nn/modules/layers.h"
#include "nn/modules/shared_mlp.h"

namespace g2l::nn {

/// max(8, round(base * width)): every hidden width of the networks; width 1.0 = the paper.
/// Throws unless width is finite and > 0.
int64_t scaled_width(int64_t base, double width);

/// For a head whose inputs are (3K vectors if `prefix` > 0), x1, x2, pf, g, onehot with widths
/// c1, c2, c5, c5, num_classes: entry i is the column of the OFFICIAL layout
/// ([prefix, x1, x2, g, pf, onehot]) that holds our column i ([prefix, x1, x2, pf, g, onehot]).
std::vector<int64_t> official_head_columns(int64_t prefix, int64_t c1, int64_t c2, int64_t c5,
                                           int64_t num_classes);

/// The backbone taps and the class, kept as separate tensors so a head can consume them with
/// concat_conv1x1 without materialising the tiled 2256-channel input.
struct PointFeatures {
    Tensor x1;      ///< [B, c1, N] after conv2 + bn2 + ReLU (64 at width 1)
    Tensor x2;      ///< [B, c2, N] after conv4 + bn4 + ReLU (128)
    Tensor pf;      ///< [B, c5, N] after conv5 + bn5, no ReLU (1024)
    Tensor g;       ///< [B, c5] max of pf over the points (the global feature)
    Tensor onehot;  ///< [B, num_classes]
    /// The same data with no autograd history (handles alias; nothing is copied).
    PointFeatures detached() const;
    /// {x1, x2, pf}, the per-point part in head column order.
    std::vector<Tensor> point() const { return {x1, x2, pf}; }
    /// {g, onehot}, the global part in head column order.
    std::vector<Tensor> global() const { return {g, onehot}; }
};

/// Per-class output heads (G2LConfig::class_heads): `x` holds one block of F channels per
/// class, [B, C*F] or [B, C*F, N]; returns the block of each sample's class as [B, F] or
/// [B, F, N] (a one-hot-weighted sum, so gradients reach only that block). Throws naming the
/// shapes unless x's channel count is a multiple of onehot's C.
Tensor select_class_block(const Tensor& x, const Tensor& onehot);

/// Throws unless x is [B, 3, N] with B, N > 0 (f32/f64) and onehot is [B, num_classes] of the
/// same dtype; the message names `who` and the offending shape.
void check_points_input(const char* who, const Tensor& x, const Tensor& onehot,
                        int64_t num_classes);

/// PointNet backbone (spec §4.1): conv1..conv5 3->64->64->64->128->1024 (scaled), BN after
/// each, ReLU except after conv5. Parameters conv<i>.weight/bias, bn<i>.* (i = 1..5).
class PointBackbone : public SharedMlp {
public:
    PointBackbone(double width, Rng& rng);
    /// x: [B, 3, N] -> the taps x1, x2, pf and g (onehot is stored as given).
    PointFeatures forward_features(const Tensor& x, const Tensor& onehot);
    int64_t c1, c2, c5;  ///< tap widths (64, 128, 1024 at width 1)
};

/// A point MLP whose first layer is a concat_conv1x1 over (per-point, global) features:
/// conv1 [h1, in_point + in_global], then conv<i> h_{i-1} -> h_i; BN after every layer, ReLU
/// after every layer except (unless relu_last) the last.
class ConcatMlp : public Module {
public:
    ConcatMlp(int64_t in_point, int64_t in_global, const std::vector<int64_t>& hidden, Rng& rng,
              bool relu_last);
    /// point: tensors [B, Ci, N] (channels summing to in_point); global: [B, Cj] (summing to
    /// in_global) -> [B, hidden.back(), N].
    Tensor forward(const std::vector<Tensor>& point, const std::vector<Tensor>& global);
    int64_t out_channels() const { return hidden_.back(); }

private:
    std::vector<int64_t> hidden_;
    std::vector<std::shared_ptr<Conv1x1>> convs_;
    std::vector<std::shared_ptr<BatchNorm>> bns_;
    bool relu_last_;
};

/// Seg_3D (spec §4.2): backbone + head 2256 -> 512 -> 256 -> 128 -> 128 (BN + ReLU),
/// Dropout(p), conv 128 -> 2, log_softmax over the channels.
/// Children: backbone, head (ConcatMlp), drop, out (Conv1x1).
class SegNet : public Module {
public:
    SegNet(double width, int64_t num_classes, double dropout, Rng& rng, uint64_t dropout_seed);
    /// x: [B, 3, N], onehot: [B, C] -> log-probabilities [B, 2, N] (channel 1 = object).
    Tensor forward(const Tensor& x, const Tensor& onehot);

private:
    int64_t num_classes_;
    std::shared_ptr<PointBackbone> backbone_;
    std::shared_ptr<ConcatMlp> head_;
    std::shared_ptr<Dropout> drop_;
    std::shared_ptr<Conv1x1> out_;
};

/// Point_center_res, the translation residual (spec §4.3): mlp 3 -> 128 -> 256 -> 512 (BN, ReLU
/// except the last), max over points, concat one-hot, fc 528 -> 256 (BN, ReLU) -> 128 (BN, no
/// ReLU), Dropout(p), out 128 -> 3. The official unused conv4 (512 -> 1024) is not built.
/// Children: mlp (SharedMlp), fc (Mlp), drop, out (Linear).
class TNet : public Module {
public:
    TNet(double width, int64_t num_classes, double dropout, Rng& rng, uint64_t dropout_seed);
    /// x: [B, 3, M] (object points minus their mean, mm), onehot: [B, C] -> residual [B, 3] (mm).
    Tensor forward(const Tensor& x, const Tensor& onehot);

private:
    int64_t num_classes_;
    std::shared_ptr<SharedMlp> mlp_;
    std::shared_ptr<Mlp> fc_;
    std::shared_ptr<Dropout> drop_;
    std::shared_ptr<Linear> out_;
};

/// Block A's outputs.
struct EvfOut {
    Tensor vectors;      ///< [B, 3K, N]: for point n, channels 3k..3k+2 point towards keypoint k
    PointFeatures feat;  ///< the head input, DETACHED (what blocks B and C consume)
};

/// Point_box_v_es, block A (spec §4.4): own backbone + head as SegNet's, output 3K channels
/// (per-point vectors to the K keypoints; unit-normalised by the loss / inference, not here).
/// Children: backbone, head, drop, out.
class EvfNet : public Module {
public:
    /// class_heads: the output layer has one 3K block per class (select_class_block).
    EvfNet(double width, int64_t num_classes, int64_t num_keypoints, double dropout, Rng& rng,
           uint64_t dropout_seed, bool class_heads = false);
    /// x: [B, 3, N] canonical points, onehot [B, C]. The head sees the live backbone features,
    /// so any loss on `vectors` trains the head AND this backbone (as the official code).
    EvfOut forward(const Tensor& x, const Tensor& onehot);

private:
    int64_t num_classes_, num_keypoints_;
    bool class_heads_;
    std::shared_ptr<PointBackbone> backbone_;
    std::shared_ptr<ConcatMlp> head_;
    std::shared_ptr<Dropout> drop_;
    std::shared_ptr<Conv1x1> out_;
};

/// Rotation_pre, block B (spec §4.5): mlp over [vectors (3K), feat (2256)] -> 1024 -> 512 -> 256
/// (BN, ReLU), max over points, fc 256 -> 256 -> 128 -> 128 (BN, ReLU on [B, C] rows),
/// Dropout(p), out 128 -> 3K. With use_vectors == false (the baseline without EVF) the input is
/// the feature alone, and the network owns a `backbone` that its own loss trains (otherwise the
/// baseline's features would stay random). Children: [backbone], mlp, fc, drop, out.
class RotNet : public Module {
public:
    RotNet(double width, int64_t num_classes, int64_t num_keypoints, bool use_vectors,
           double dropout, Rng& rng, uint64_t dropout_seed, bool class_heads = false);
    /// vectors: [B, 3K, N] (block A's output, not detached) if use_vectors, else undefined;
    /// feat: features of the same N points -> keypoints [B, K, 3] (canonical frame, mm).
    Tensor forward(const Tensor& vectors, const PointFeatures& feat);
    /// The baseline's own backbone features (live, not detached); throws if use_vectors.
    PointFeatures features(const Tensor& x, const Tensor& onehot);
    bool use_vectors() const { return use_vectors_; }

private:
    int64_t num_classes_, num_keypoints_;
    bool use_vectors_, class_heads_;
    std::shared_ptr<PointBackbone> backbone_;
    std::shared_ptr<ConcatMlp> mlp_;
    std::shared_ptr<Mlp> fc_;
    std::shared_ptr<Dropout> drop_;
    std::shared_ptr<Linear> out_;
};

/// Point_box_R_es, block C (spec §4.6): Dropout(p_in = 0.3) on the input feature, mlp 2256 ->
/// 256 (BN, ReLU) -> 128 (BN, no ReLU), max over points, out 128 -> 3K (no BN).
///
/// Dropout choice: the official code drops elements of the tiled [B, 2256, N] tensor. Here the
/// per-point tensors x1, x2, pf are dropped element-wise, and the global vectors g and onehot
/// are dropped as [B, C] vectors, i.e. one mask entry per (sample, channel) shared by all points
/// (the tiled tensor is never built). Children: drop, mlp, out.
class RreNet : public Module {
public:
    RreNet(double width, int64_t num_classes, int64_t num_keypoints, double dropout_in, Rng& rng,
           uint64_t dropout_seed, bool class_heads = false);
    /// feat: detached features of N points -> residual [B, K, 3] (mm).
    Tensor forward(const PointFeatures& feat);

private:
    int64_t num_classes_, num_keypoints_;
    bool class_heads_;
    std::shared_ptr<Dropout> drop_;
    std::shared_ptr<ConcatMlp> mlp_;
    std::shared_ptr<Linear> out_;
};

}  // namespace g2l::nn
