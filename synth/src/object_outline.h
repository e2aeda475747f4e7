#pragma once
// The object's rest outline by shape, and where a disc moving straight at it
// first touches it (private to synth; scenario_geometry.cpp and the scenario's
// validation use them).
//
// Everything here is in the object's own frame: image pixels before
// object.rotation_deg turns the object (near side at small y). Polygons are
// closed implicitly and clockwise on screen.

#include "calib/core/types.h"
#include "calib/synth/scenario.h"

#include <vector>

namespace calib::synth::outline_detail {

/// The shape of `scenario.object` cut from ObjectRectPx, px, not yet turned.
std::vector<Vec2> UnturnedOutlinePx(const Scenario& scenario);

/// `p` turned by object.rotation_deg about the centre of ObjectRectPx
/// (clockwise on screen for a positive angle); `p` itself when the angle is 0.
Vec2 TurnPx(const Scenario& scenario, const Vec2& p);

/// The vector `v` turned by object.rotation_deg; `v` itself when the angle is 0.
Vec2 TurnDirection(const Scenario& scenario, const Vec2& v);

/// The centre y of a disc of `radius_px` (>= 0) centred on the vertical line
/// x = `x_px` that moves down (+y) from far above until it first touches
/// `polygon`; +infinity when the disc passes beside it.
double FirstTouchFromAbove(const std::vector<Vec2>& polygon, double x_px, double radius_px);

/// As FirstTouchFromAbove for a disc moving up (-y) from far below;
/// -infinity when it passes beside the polygon.
double FirstTouchFromBelow(const std::vector<Vec2>& polygon, double x_px, double radius_px);

}  // namespace calib::synth::outline_detail
