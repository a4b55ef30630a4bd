// Engagement and mechanistic forces: one work item per time step. It walks the flutes and the edge
// elements that can reach material in this batch, eight elements at a time as float8 lanes, so CPU
// devices (PoCL) run it as SIMD and GPUs as plain scalar code. Per-element rotations (flute pitch
// and helix lag) are precomputed: a step costs one sincos plus a few multiply-adds per element; only
// lanes whose chip thickness is positive look up the dexel grid. Twin: engage_twin in twins.cpp.
//
// steps:  8 floats per step: tip x, y, z; feed per tooth x, y, z; A = pi/2 - theta; spin (+1/-1)
// elems:  structure of arrays, each `stride` floats (a multiple of 8, padding has nr = nz = 0):
//         r, z, nr, nz, db, z_lo, z_hi
// rot:    per spin (+1 first, then -1), per flute: cos psi[stride], sin psi[stride] with
//         psi = -2 pi j / N + spin * lag, so the edge direction is alpha = A + psi
// cells:  2 float4 per ray: lo[4], hi[4]
// coef:   Ktc, Krc, Kac, Kte, Kre, Kae, holder face height, minimum chip thickness
// out:    12 floats per step (StepResult)
__kernel void engage(const int n_steps, __global const float* steps, __global const float* elems,
                     __global const float* rot, const int stride, const int n_flutes, const int bottom_count,
                     const int element_end, __global const float4* cells, const float x0, const float y0,
                     const float inv_cell, const int nx, const int ny, __constant float* coef,
                     __global float* out) {
    const int i = get_global_id(0);
    if (i >= n_steps) return;
    const float4 s0 = vload4(0, steps + 8 * i);
    const float4 s1 = vload4(1, steps + 8 * i);
    const float tx = s0.x, ty = s0.y, tz = s0.z;
    const float fx = s0.w, fy = s1.x, fz = s1.y;
    const float spin = s1.w;
    float ca;
    const float sa = sincos(s1.z, &ca);
    const float fxy = sqrt(fx * fx + fy * fy);
    const float px = fxy > 1e-12f ? -fy / fxy : 1.0f, py = fxy > 1e-12f ? fx / fxy : 0.0f;
    const float Ktc = coef[0], Krc = coef[1], Kac = coef[2], Kte = coef[3], Kre = coef[4], Kae = coef[5];
    const float face_z = coef[6], min_chip = coef[7];
    float8 Fx = 0, Fy = 0, Fz = 0, T = 0, Mx = 0, My = 0, chip = 0;
    float8 qmin = 1e30f, qmax = -1e30f, zmin = 1e30f, zmax = -1e30f;
    int8 engaged = 0;
    const int first = fz >= 0.0f ? bottom_count : 0;
    const int c_begin = first / 8 * 8;
    const int8 lane = (int8)(0, 1, 2, 3, 4, 5, 6, 7);
    __global const float* el_r = elems;
    __global const float* el_z = elems + stride;
    __global const float* el_nr = elems + 2 * stride;
    __global const float* el_nz = elems + 3 * stride;
    __global const float* el_db = elems + 4 * stride;
    __global const float* el_zlo = elems + 5 * stride;
    __global const float* el_zhi = elems + 6 * stride;
    __global const float* rot_spin = rot + (spin < 0.0f ? 2 * n_flutes * stride : 0);
    for (int j = 0; j < n_flutes; ++j) {
        __global const float* rc = rot_spin + 2 * j * stride;
        __global const float* rs = rc + stride;
        for (int c = c_begin; c < element_end; c += 8) {
            const float8 cp = vload8(0, rc + c), sp = vload8(0, rs + c);
            const float8 cu = ca * cp - sa * sp;
            const float8 su = sa * cp + ca * sp;
            const float8 nr = vload8(0, el_nr + c), nz = vload8(0, el_nz + c);
            const float8 h = nr * (fx * cu + fy * su) + nz * fz;
            const int8 e = lane + c;
            int8 ok = (e >= first) & (e < element_end) & (h > min_chip);
            if (!any(ok)) continue;
            const float8 r = vload8(0, el_r + c), ez = vload8(0, el_z + c);
            const int8 ci = convert_int8_rtn((tx + r * cu - x0) * inv_cell);
            const int8 cj = convert_int8_rtn((ty + r * su - y0) * inv_cell);
            ok &= (ci >= 0) & (cj >= 0) & (ci < nx) & (cj < ny);
            const float8 z = tz + ez;
            int lane_ok[8], cell[8], inside[8];
            float lane_z[8];
            vstore8(ok, 0, lane_ok);
            vstore8(cj * nx + ci, 0, cell);
            vstore8(z, 0, lane_z);
            for (int l = 0; l < 8; ++l) {
                inside[l] = 0;
                if (lane_ok[l]) {
                    const float4 lo = cells[2 * cell[l]], hi = cells[2 * cell[l] + 1];
                    const float zl = lane_z[l];
                    inside[l] = any(isgreaterequal((float4)(zl), lo) & isless((float4)(zl), hi)) ? -1 : 0;
                }
            }
            const int8 m = vload8(0, inside);
            if (!any(m)) continue;
            const float8 db = vload8(0, el_db + c);
            const float8 dFt = select((float8)(0.0f), (Ktc * h + Kte) * db, m);
            const float8 dFr = select((float8)(0.0f), (Krc * h + Kre) * db, m);
            const float8 dFa = select((float8)(0.0f), (Kac * h + Kae) * db, m);
            const float8 normal = dFr * nr + dFa * nz;
            const float8 ex = -spin * dFt * su - normal * cu;
            const float8 ey = spin * dFt * cu - normal * su;
            const float8 fz_e = -dFr * nz + dFa * nr;
            Fx += ex;
            Fy += ey;
            Fz += fz_e;
            T += r * dFt;
            const float8 lz = ez - face_z;
            Mx += r * su * fz_e - lz * ey;
            My += lz * ex - r * cu * fz_e;
            chip = fmax(chip, select((float8)(0.0f), h, m));
            const float8 q = r * (cu * px + su * py);
            qmin = fmin(qmin, select((float8)(1e30f), q, m));
            qmax = fmax(qmax, select((float8)(-1e30f), q, m));
            zmin = fmin(zmin, select((float8)(1e30f), vload8(0, el_zlo + c), m));
            zmax = fmax(zmax, select((float8)(-1e30f), vload8(0, el_zhi + c), m));
            engaged -= m;
        }
    }
    const float4 F4x = Fx.lo + Fx.hi, F4y = Fy.lo + Fy.hi, F4z = Fz.lo + Fz.hi;
    const float4 T4 = T.lo + T.hi, M4x = Mx.lo + Mx.hi, M4y = My.lo + My.hi;
    const float4 c4 = fmax(chip.lo, chip.hi), qn4 = fmin(qmin.lo, qmin.hi), qx4 = fmax(qmax.lo, qmax.hi);
    const float4 zn4 = fmin(zmin.lo, zmin.hi), zx4 = fmax(zmax.lo, zmax.hi);
    const int4 n4 = engaged.lo + engaged.hi;
    const int n = n4.x + n4.y + n4.z + n4.w;
    __global float* o = out + 12 * i;
    o[0] = F4x.x + F4x.y + F4x.z + F4x.w;
    o[1] = F4y.x + F4y.y + F4y.z + F4y.w;
    o[2] = F4z.x + F4z.y + F4z.z + F4z.w;
    o[3] = T4.x + T4.y + T4.z + T4.w;
    o[4] = M4x.x + M4x.y + M4x.z + M4x.w;
    o[5] = M4y.x + M4y.y + M4y.z + M4y.w;
    o[6] = fmax(fmax(c4.x, c4.y), fmax(c4.z, c4.w));
    o[7] = n ? fmin(fmin(qn4.x, qn4.y), fmin(qn4.z, qn4.w)) : 0.0f;
    o[8] = n ? fmax(fmax(qx4.x, qx4.y), fmax(qx4.z, qx4.w)) : 0.0f;
    o[9] = n ? fmin(fmin(zn4.x, zn4.y), fmin(zn4.z, zn4.w)) : 0.0f;
    o[10] = n ? fmax(fmax(zx4.x, zx4.y), fmax(zx4.z, zx4.w)) : 0.0f;
    o[11] = (float)n;
}
