// Joint projection, the end of stage 6 (integration): a joint whose two points the step left
// further apart than settings.joint_projection (a hard landing on a ragdoll's limb, a heavy body
// swung on a light one) has them moved together to that distance, each body by its share of the
// correction — inverse mass and inverse inertia about the point, as Box2D's position solver
// corrects a joint — without changing any velocity: the joint's soft spring still does the
// dynamics, the projection only bounds how far it opens. Joints name their points in their
// descriptors (`holds_points`), so a new joint type is projected with no code here.
#pragma once
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/settings.h"
#include "runtime/ppe/step_stats.h"

namespace cellphys::ppe {

/// Moves the awake bodies of joints opened wider than s.joint_projection (0: off) until every
/// one is within it or kProjectionPasses passes are done, in force order (the same bits on any
/// machine). Counts the joints the first pass moved in st.projected_joints.
void project_joints(const WorldSettings& s, const std::vector<WorldForce>& forces, std::vector<WorldBody>& bodies,
                    StepStats& st);

inline constexpr int kProjectionPasses = 4;

}  // namespace cellphys::ppe
