// The 3D model of §8.10: points and the edges between them, built from correspondence tracks.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "shared/reconstruction/correspondence.h"

namespace idi {

struct ModelPoint {
  int id = 0;
  Vec3d xyz = Vec3d::Zero();  // world frame (mm in the workcell)
  std::vector<Observation> observations;
  double reprojection_rms_px = 0;
};

struct StructureModel {
  std::vector<ModelPoint> points;
  std::vector<std::pair<int, int>> edges;  // indices into points, i < j
};

struct ModelOptions {
  int min_views_for_edge = 2;        // an edge must be seen (both ends on one image line) in this many views
  double segment_margin_px = 3.0;    // the edge's midpoint must lie on the confirmed image segment
  bool Check() const { return min_views_for_edge >= 1 && segment_margin_px >= 0; }
};

// Points from the point tracks; an edge joins two points that lie on one EMPL line in at least
// `min_views_for_edge` views, are adjacent along it (no other model point between them on that line),
// and whose midpoint projects onto the line's confirmed segment.
StructureModel BuildModel(const Correspondences& correspondences, const std::vector<CorrespondenceView>& views,
                          const ModelOptions& options = {});

// PLY (ASCII) with `vertex` (x, y, z) and `edge` (vertex1, vertex2) elements.
std::string ModelToPly(const StructureModel& model);

}  // namespace idi
