// Internal: the cutting law, how a chip becomes force on an edge element. One law today, Altintas'
// linear edge-force model (Manufacturing Automation, 2nd ed., 2012, ch. 2), per element of engaged
// length db cutting a chip of thickness h:
//   dFt = Ktc h db + Kte db,   dFr = Krc h db + Kre db,   dFa = Kac h db + Kae db
// The K.c terms shear the chip (force per chip area), the K.e terms rub the edge (force per edge
// length). The kernels evaluate it per element (engage.cl, and kernels::element_force for the
// scalar twin) from the coefficient block this module fills; docs/force_model.md, "Conventions",
// gives the directions.
#pragma once

#include "force_model/force_model.hpp"
#include "kernels/engine_kernels.hpp"

namespace cutload::force_model {

struct LinearEdgeForceLaw {
    double Ktc_N_mm2 = 0, Krc_N_mm2 = 0, Kac_N_mm2 = 0;   // chip-area (shearing) coefficients
    double Kte_N_mm = 0, Kre_N_mm = 0, Kae_N_mm = 0;      // edge (ploughing) coefficients
    // Chips thinner than this rub rather than cut and carry no force at all, edge terms included
    // (EngineSettings::min_chip_mm says why).
    double min_chip_mm = 0;
};

LinearEdgeForceLaw cutting_law(const Material& material, double min_chip_mm);

// The law as the engagement kernels take it: their coefficient block and minimum chip.
void set_kernel_law(const LinearEdgeForceLaw& law, kernels::EngageParams& params);

}  // namespace cutload::force_model
