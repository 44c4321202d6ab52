// SPDX-License-Identifier: MIT
// The frames of a video, in order: a BOP scene folder (depth/, rgb/, scene_camera.json) or a
// list file. Only the names and cameras are read here; each frame's images are loaded when it
// is its turn, so one bad frame is that frame's error and the others go on (g2l_infer --scene).
#pragma once

#include <string>
#include <vector>

#include "data/bop.h"

namespace g2l::data {

struct SequenceFrame {
    int image_id = 0;   ///< BOP: the number of the depth file's name; a list: the line's index
    std::string depth;  ///< 16-bit depth PNG
    std::string rgb;    ///< colour image; empty when the frame has none
    CameraFile camera;  ///< valid when camera_error is empty
    /// Why this frame has no camera (its scene_camera.json entry is missing or invalid): the
    /// frame fails with this message, the sequence goes on.
    std::string camera_error;
};

/// A BOP scene folder: every depth/NNNNNN.png in the order of its number, its rgb/NNNNNN.png
/// (or .jpg) when there, and its scene_camera.json entry. Throws g2l::Error naming the path for
/// a missing folder, no depth/ folder or no depth image in it, a depth file whose name is not a
/// number, or a missing or unreadable scene_camera.json.
std::vector<SequenceFrame> list_bop_scene(const std::string& dir);

/// A list file: one frame per line, "DEPTH_PNG [RGB_IMAGE]" (paths relative to the list's
/// folder unless absolute; blank lines and '#' comments skipped), all taken with `camera`;
/// image ids 1, 2, ... in the order of the lines. Throws g2l::Error naming the file and line for
/// a missing file, a line with more than two paths, or no frame.
std::vector<SequenceFrame> list_frames_file(const std::string& path, const CameraFile& camera);

}  // namespace g2l::data
