// The trajectory CSV of `cellphys run --out`: a header, then one row per body and written step,
// step,t,body,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz, floats in their shortest exact form.
#pragma once
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"

namespace cellphys::cli {

// A body id as a CSV field (quoted when it holds a comma, a quote or a line break).
std::string csv_field(const std::string& s);

// A float in its shortest exact form, appended to a CSV line.
void put_float(std::string& line, float v);

void write_trajectory_header(FILE* f);

// One row per body of `bodies` (in that order, `ids` its body column) at `step`, time `t`.
void write_trajectory_rows(FILE* f, const ppe::World& world, const std::vector<ppe::BodyId>& bodies, uint64_t step,
                           double t, const std::vector<std::string>& ids);

}  // namespace cellphys::cli
