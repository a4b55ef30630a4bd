#include "cutting_law.hpp"

namespace cutload::force_model {

LinearEdgeForceLaw cutting_law(const Material& material, double min_chip_mm) {
    return {material.Ktc_N_mm2, material.Krc_N_mm2, material.Kac_N_mm2,
            material.Kte_N_mm,  material.Kre_N_mm,  material.Kae_N_mm, min_chip_mm};
}

void set_kernel_law(const LinearEdgeForceLaw& law, kernels::EngageParams& params) {
    params.k = {law.Ktc_N_mm2, law.Krc_N_mm2, law.Kac_N_mm2, law.Kte_N_mm, law.Kre_N_mm, law.Kae_N_mm};
    params.min_chip_mm = law.min_chip_mm;
}

}  // namespace cutload::force_model
