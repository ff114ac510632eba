// Synthetic multi-view features from 3D wireframes, for correspondence and reconstruction tests that
// must not depend on image processing: vertices project to IDI points (with pixel noise), edges to
// EMPL lines whose confirmed segments stop short of the corners (as real ones do), plus clutter lines
// and points that belong to nothing in 3D. Ground truth (which vertex each point is) is kept apart.
#pragma once

#include <random>
#include <vector>

#include "shared/reconstruction/correspondence.h"

namespace idi::test {

struct Wireframe {
  std::vector<Vec3d> vertices;
  std::vector<std::pair<int, int>> edges;
};

// An axis-aligned box (8 vertices, 12 edges) with one corner at `origin`, rotated by yaw about z.
Wireframe Box(const Vec3d& origin, const Vec3d& size, double yaw_rad = 0);
// Appends `b` to `a` (vertex indices shifted).
void Append(Wireframe* a, const Wireframe& b);

// A camera at `centre` looking at `target`, world z up.
Rigid3d LookAt(const Vec3d& centre, const Vec3d& target);

struct SyntheticViewOptions {
  double point_noise_px = 0.05;
  double line_shortening_px = 3.0;  // confirmed segments stop this far from the corners
  double extension_px = 12.0;
  int clutter_lines = 6;
  double min_edge_px = 12.0;        // shorter projected edges are not detected
};

struct SyntheticView {
  ViewFeatures features;
  std::vector<int> point_vertex;  // ground truth: the wireframe vertex of each point, -1 for clutter
  CameraModel camera;
  Rigid3d cam_from_world;
};

// Projects the wireframe into a view. Visibility: in front of the camera and inside the image (no
// self-occlusion - wireframes are transparent here).
SyntheticView MakeView(const Wireframe& w, const CameraModel& camera, const Rigid3d& cam_from_world,
                       const SyntheticViewOptions& options, std::mt19937* rng);

}  // namespace idi::test
