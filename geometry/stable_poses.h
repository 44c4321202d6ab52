// SPDX-License-Identifier: MIT
// Stable resting poses of a rigid object on a horizontal plane, with the probability that a
// randomly dropped object comes to rest in each (quasi-static model). The object rests on a face
// of its convex hull; with gravity along the model-frame direction d, the centre of mass sits at
// height h(d) = max_v (v - com) . d above the plane (the support function of the hull), and the
// object rolls down h until a local minimum: those minima are the stable poses, and the share of
// uniformly random drop directions that roll into one is its probability (the basin of
// attraction on the sphere; Wiegley et al. 1996, Kriegman 1997). No explicit hull is built: h is
// evaluated over the mesh vertices, whose support function equals the hull's. Lengths in mm.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "geometry/types.h"

namespace g2l::geom {

struct StablePose {
    Eigen::Vector3f down = -Eigen::Vector3f::UnitZ();  ///< model-frame gravity direction (unit)
    double height = 0;       ///< height of the centre of mass above the plane (mm)
    double probability = 0;  ///< share of random drops that end here (they sum to 1)
};

struct StablePoseOptions {
    int directions = 3000;         ///< Fibonacci-sphere drop directions
    int neighbours = 8;            ///< sphere neighbours of each direction for the descent
    double merge_deg = 3.0;        ///< minima closer than this are one pose
    double min_probability = 0.01; ///< poses less likely are dropped (the rest renormalised)
    int max_vertices = 20000;      ///< vertices used (evenly strided) for h
};

/// Centre of mass of the mesh as a solid of uniform density (signed tetrahedra); falls back to
/// the area-weighted surface centroid when the mesh encloses (almost) no volume, and to the vertex
/// mean when it has no faces. Throws g2l::Error for a mesh without vertices.
Eigen::Vector3d centre_of_mass(const Mesh& mesh);

/// The stable poses of `mesh` about `com` (model frame), most probable first. Throws g2l::Error
/// for a mesh without vertices or options out of range (naming the field and value).
std::vector<StablePose> stable_poses(const Mesh& mesh, const Eigen::Vector3d& com,
                                     const StablePoseOptions& opt = {});

/// A rotation taking the pose's model-frame `down` onto world -z (the gravity of a z-up world);
/// compose with a yaw about z for the other equivalent resting orientations.
Eigen::Matrix3d resting_rotation(const StablePose& pose);

}  // namespace g2l::geom
