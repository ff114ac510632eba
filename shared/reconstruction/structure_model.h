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
  // The views that see an edge must look at it from directions at least this far apart about its axis.
  // Two points fall on one image line by accident when the camera lies in the plane of a true edge and
  // a point beyond it: an unseen corner then projects onto the point, and the image line along the true
  // edge seems to join them. Cameras in that plane see the same accident, from directions about the edge
  // less than a degree apart (a bracket's leg top and its foot's far corner from two 45 deg stations).
  // A true edge seen from two stations is seen from directions tens of degrees apart; in the twin's
  // scans about 1 % of true edges fall under 2 deg (edges along the baseline of the one station's two
  // cameras that saw them). An edge missed this way makes the grasp planner's cross-sections smaller;
  // an accidental one adds a wall that is not there.
  double min_edge_spread_deg = 2.0;
  // InvalidArgument naming the option that is out of range (NaN included).
  Status Check() const;
};

// Points from the point tracks; an edge joins two points that lie on one EMPL line in at least
// `min_views_for_edge` views, are adjacent along it (no other model point between them on that line),
// whose midpoint projects onto the line's confirmed segment, and which those views see from directions
// `min_edge_spread_deg` apart about the edge.
StructureModel BuildModel(const Correspondences& correspondences, const std::vector<CorrespondenceView>& views,
                          const ModelOptions& options = {});

// PLY (ASCII) with `vertex` (x, y, z) and `edge` (vertex1, vertex2) elements.
std::string ModelToPly(const StructureModel& model);

}  // namespace idi
