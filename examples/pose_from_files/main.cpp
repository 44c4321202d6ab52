// SPDX-License-Identifier: MIT
// Embedding g2l: the 6D pose of one object from a depth image, a camera and a 2D box.
//   pose_from_files MODEL DEPTH_PNG FX FY CX CY DEPTH_SCALE OBJ_ID X Y W H
// Prints "obj <id>: <status>" and, for a pose, R (row-major) and t (mm). Exit code 0 when the
// pose was found, 1 when the box gave none, 2 for bad arguments or files.
#include <g2l/pose_estimator.h>

#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

int main(int argc, char** argv) {
    if (argc != 13) {
        std::fprintf(stderr, "usage: %s MODEL DEPTH_PNG FX FY CX CY DEPTH_SCALE OBJ_ID X Y W H\n",
                     argv[0]);
        return 2;
    }
    try {
        const cv::Mat depth = cv::imread(argv[2], cv::IMREAD_ANYDEPTH);
        if (depth.empty() || depth.type() != CV_16UC1) {
            std::fprintf(stderr, "%s: not a 16-bit depth PNG\n", argv[2]);
            return 2;
        }
        g2l::PoseEstimator estimator(argv[1]);  // throws with a clear message on a bad file
        g2l::FrameView frame;
        frame.width = depth.cols;
        frame.height = depth.rows;
        frame.depth_u16 = depth.ptr<uint16_t>();
        frame.depth_scale = std::atof(argv[7]);
        frame.K = {std::atof(argv[3]), std::atof(argv[4]), std::atof(argv[5]), std::atof(argv[6])};
        const g2l::ObjectBox box{std::atoi(argv[8]), std::atoi(argv[9]), std::atoi(argv[10]),
                                 std::atoi(argv[11]), std::atoi(argv[12]), 1.0};
        const g2l::ObjectPose pose = estimator.estimate(frame, {box}).at(0);
        std::printf("g2l %s, obj %d: %s\n", g2l::version(), pose.obj_id, g2l::to_string(pose.status));
        if (!pose.ok()) return 1;
        std::printf("R = [%.6f %.6f %.6f; %.6f %.6f %.6f; %.6f %.6f %.6f]\nt = [%.2f %.2f %.2f] mm\n",
                    pose.R[0], pose.R[1], pose.R[2], pose.R[3], pose.R[4], pose.R[5], pose.R[6],
                    pose.R[7], pose.R[8], pose.t[0], pose.t[1], pose.t[2]);
        std::printf("%.1f ms\n", pose.timings.total_ms);
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 2;
    }
}
