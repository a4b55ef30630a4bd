// Engagement and mechanistic forces: one work item per time step. It walks the flutes and the edge
// elements that can reach material in this batch, eight elements at a time as float8 lanes, so CPU
// devices (PoCL) run it as SIMD and GPUs as plain scalar code. Per-element rotations (flute pitch
// and helix lag) are precomputed and each step carries cos/sin of its own angle, so an element costs
// a few multiply-adds; only lanes whose chip thickness is positive and whose edge point lies over the
// stock look up the dexel grid. Twin: engage_twin in twins.cpp.
//
// steps:  8 floats per step: tip x, y, z; feed per tooth x, y, z; cos A, sin A with A = pi/2 - theta
// spin:   +1 (M03) or -1 (M04) for the whole batch
// elems:  structure of arrays, each `stride` floats (a multiple of 8, padding has nr = nz = 0):
//         r, z, nr, nz, db, z_lo, z_hi, inv_span (1 / (z_hi - z_lo), 0 for flat-bottom elements)
// rot:    per spin (+1 first, then -1), per flute: cos psi[stride], sin psi[stride] with
//         psi = -2 pi j / N + spin * lag, so the edge direction is alpha = A + psi
// cells:  2 float4 per ray: lo[4], hi[4], each XOR-ed with base_lo / base_hi (RayCodec)
// walls:  2 float4 per ray, the deepest wall then the lowest (empty when it is the same): clearance
//         (bits XOR-ed with NO_WALL's), z_from, normal x, y (Wall)
// tops:   per ray, the top of its material (bits XOR-ed with top_base's, so a ray never cut is 0),
//         for a ray with the wall mark the highest of its own and its eight neighbours' (remove.cl's
//         refresh_tops keeps them); skip_below_tops: whether lanes over a ray no higher than the
//         element are left out
// coef:   Ktc, Krc, Kac, Kte, Kre, Kae, holder face height, minimum chip thickness, cell size,
//         wall tolerance
// out:    12 floats per step (StepResult)
//
// Axial weighting: an element with an axial span [z_lo, z_hi] cuts with the fraction of that span
// that lies inside material on the ray under its edge point, so the engaged length follows the
// dexel interval ends exactly instead of jumping by whole elements. Flat-bottom elements (no axial
// span) cut when their edge point is inside material, with the chip limited to the material on the
// ray between the point and the previous tooth's pass (h above it).
//
// min/max rather than fmin/fmax throughout: no NaN reaches them, and the NaN-safe forms cost PoCL
// several instructions each.

// Overlaps shorter than this are float round-off (kSliverMm in engine_kernels.hpp).
#define SLIVER 1e-4f
#define EMPTY_LO 1e30f
#define EMPTY_HI -1e30f
#define NO_WALL 1e30f
#define WALL_MARK 2e30f   // kWallMark: a ray with a recorded wall holds it in its last lo slot

// An element cut over all but this fraction of its span counts as fully engaged when the engaged
// axial extent is reported (at most 1e-5 of an element off); the weight itself is always exact.
#define FULL_WEIGHT 0.9999f

float4 decode(const float4 stored, const uint4 base) { return as_float4(as_uint4(stored) ^ base); }

// The material at the edge point (u, v) (grid units, on the stock), as a ray's lo and hi. The
// cell's ray describes its centre; a wall recorded there places the point itself. On the swept side
// of the wall the material from the wall's foot up is gone. On the far side of a wall that passes
// between a swept centre and the point, the point has the material of the ray one cell across the
// wall. The ray's second (lower) wall only takes out the material on its swept side. Twin:
// material_at in twins.cpp.
__attribute__((always_inline)) void material_at(__global const float4* cells, __global const float4* walls, const uint4 base_lo,
                 const uint4 base_hi, const int c, const float u, const float v, const int nx, const int ny,
                 const float cell_mm, const float wall_tol, float4* lo, float4* hi) {
    *lo = decode(cells[2 * c], base_lo);
    *hi = decode(cells[2 * c + 1], base_hi);
    if ((*lo).w != WALL_MARK) return;   // no wall: the ray says so in its last slot
    const int ci = (int)u, cj = (int)v;   // u, v >= 0: truncation is floor
    const float fu = u - (float)ci - 0.5f, fv = v - (float)cj - 0.5f;
    const float4 w = walls[2 * c], w_low = walls[2 * c + 1];
    const float clearance = as_float(as_uint(w.x) ^ as_uint(NO_WALL));
    const float clearance_low = as_float(as_uint(w_low.x) ^ as_uint(NO_WALL));
    float swept_from = NO_WALL;   // material from this height up is gone
    if (clearance + (fu * w.z + fv * w.w) * cell_mm <= wall_tol) {
        swept_from = w.y;
    } else if (clearance <= 0.0f) {
        // One cell over, whatever the stored normal says: the lookup tops (remove.cl's
        // refresh_tops) count on the ray read being one of the 3 x 3 around this one.
        const int ai = clamp((int)floor((float)ci + 0.5f + w.z), ci - 1, ci + 1);
        const int aj = clamp((int)floor((float)cj + 0.5f + w.w), cj - 1, cj + 1);
        if (ai < 0 || aj < 0 || ai >= nx || aj >= ny) {
            *lo = (float4)(EMPTY_LO);
            *hi = (float4)(EMPTY_HI);
            return;
        }
        *lo = decode(cells[2 * (aj * nx + ai)], base_lo);
        *hi = decode(cells[2 * (aj * nx + ai) + 1], base_hi);
    }
    if (clearance_low < NO_WALL && clearance_low + (fu * w_low.z + fv * w_low.w) * cell_mm <= wall_tol)
        swept_from = min(swept_from, w_low.y);
    if (swept_from < NO_WALL) {
        // Float round-off must not leave the foot itself in material (a flat bottom on the floor).
        const float4 top = min(*hi, (float4)(swept_from - SLIVER));
        const int4 keep = isgreater(top - *lo, (float4)(SLIVER)) | isless(*hi, (float4)(swept_from - SLIVER));
        *lo = select((float4)(EMPTY_LO), *lo, keep);
        *hi = select((float4)(EMPTY_HI), top, keep);
    }
}

// Length of the element span [za, zb) inside material on one ray (pieces over SLIVER).
float span_overlap(const float za, const float zb, const float4 lo, const float4 hi) {
    const float4 d = min((float4)(zb), hi) - max((float4)(za), lo);
    const float4 in = select((float4)(0.0f), d, isgreater(d, (float4)(SLIVER)));
    return (in.x + in.y) + (in.z + in.w);
}

// Lowest and highest engaged point of the span [za, zb) on one ray.
void span_clip(const float za, const float zb, const float4 lo, const float4 hi, float* clip_lo, float* clip_hi) {
    const float4 a = max((float4)(za), lo), b = min((float4)(zb), hi);
    const int4 has = isgreater(b - a, (float4)(SLIVER));
    const float4 a_in = select((float4)(1e30f), a, has), b_in = select((float4)(-1e30f), b, has);
    *clip_lo = min(min(a_in.x, a_in.y), min(a_in.z, a_in.w));
    *clip_hi = max(max(b_in.x, b_in.y), max(b_in.z, b_in.w));
}

__kernel void engage(const int n_steps, __global const float* steps, const float spin, __global const float* elems,
                     __global const float* rot, const int stride, const int n_flutes, const int bottom_count,
                     const int element_end, __global const float4* cells, __global const float4* walls,
                     const uint4 base_lo,
                     const uint4 base_hi, __global const uint* tops, const uint top_base, const int skip_below_tops,
                     const float x0,
                     const float y0, const float inv_cell, const int nx, const int ny, __constant float* coef,
                     __global float* out) {
    const int i = get_global_id(0);
    if (i >= n_steps) return;
    const float4 s0 = vload4(0, steps + 8 * i);
    const float4 s1 = vload4(1, steps + 8 * i);
    const float tx = s0.x, ty = s0.y, tz = s0.z;
    const float fx = s0.w, fy = s1.x, fz = s1.y;
    const float ca = s1.z, sa = s1.w;
    const float fxy = sqrt(fx * fx + fy * fy);
    const float px = fxy > 1e-12f ? -fy / fxy : 1.0f, py = fxy > 1e-12f ? fx / fxy : 0.0f;
    const float Ktc = coef[0], Krc = coef[1], Kac = coef[2], Kte = coef[3], Kre = coef[4], Kae = coef[5];
    const float face_z = coef[6], min_chip = coef[7], cell_mm = coef[8], wall_tol = coef[9];
    // Grid coordinates of the tip; an edge point is over the stock when 0 <= u < nx and 0 <= v < ny.
    const float tu = (tx - x0) * inv_cell, tv = (ty - y0) * inv_cell;
    const float fnx = (float)nx, fny = (float)ny;
    float8 Fx = 0, Fy = 0, Fz = 0, T = 0, Mx = 0, My = 0, chip = 0;
    float8 qmin = 1e30f, qmax = -1e30f, zmin = 1e30f, zmax = -1e30f;
    int8 engaged = 0;
    // Flat-bottom elements cut only while the tool descends. Lanes before `first` in its chunk and
    // past element_end need no mask: the bottom has h = -fz <= 0 there, and elements above the
    // highest material under the batch find none.
    const int first = fz >= 0.0f ? bottom_count : 0;
    const int c_begin = first / 8 * 8;
    __global const float* el_r = elems;
    __global const float* el_z = elems + stride;
    __global const float* el_nr = elems + 2 * stride;
    __global const float* el_nz = elems + 3 * stride;
    __global const float* el_db = elems + 4 * stride;
    __global const float* el_zlo = elems + 5 * stride;
    __global const float* el_zhi = elems + 6 * stride;
    __global const float* el_inv = elems + 7 * stride;
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
            int8 ok = h > min_chip;
            if (!any(ok)) continue;
            const float8 r = vload8(0, el_r + c);
            const float8 u = tu + r * inv_cell * cu, v = tv + r * inv_cell * su;
            ok &= (u >= 0.0f) & (v >= 0.0f) & (u < fnx) & (v < fny);
            if (!any(ok)) continue;   // the whole chunk is off the stock (a tool running along its side)
            // u, v >= 0 here, so truncation is floor.
            const int8 cell8 = convert_int8(v) * nx + convert_int8(u);
            const float8 ez = vload8(0, el_z + c);
            const float8 zlo = vload8(0, el_zlo + c), zhi = vload8(0, el_zhi + c), inv = vload8(0, el_inv + c);
            const float8 z = tz + ez, za = tz + zlo, zb = tz + zhi;
            int lane_ok[8], cell[8];
            float lane_u[8], lane_v[8], lane_z[8], lane_a[8], lane_b[8], lane_inv[8], lane_h[8], weight[8];
            vstore8(ok, 0, lane_ok);
            vstore8(h, 0, lane_h);
            vstore8(cell8, 0, cell);
            vstore8(u, 0, lane_u);
            vstore8(v, 0, lane_v);
            vstore8(z, 0, lane_z);
            vstore8(za, 0, lane_a);
            vstore8(zb, 0, lane_b);
            vstore8(inv, 0, lane_inv);
            for (int l = 0; l < 8; ++l) {
                weight[l] = 0.0f;
                if (!lane_ok[l]) continue;
                // Nothing a lookup may read at this ray (the ray itself, or the one across its wall)
                // reaches above the ray's top: when that is not above the element's lowest point, the
                // weight is 0 (no overlap over the sliver, and a flat-bottom point is inside nothing),
                // so the lookup is left out. In a pocket most edge points ahead of the tool lie over
                // stock cut down already (docs/force_model.md, "Lookups skipped").
                if (skip_below_tops && as_float(tops[cell[l]] ^ top_base) <= min(lane_a[l], lane_z[l])) continue;
                float4 lo, hi;
                material_at(cells, walls, base_lo, base_hi, cell[l], lane_u[l], lane_v[l], nx, ny, cell_mm, wall_tol, &lo,
                            &hi);
                if (lane_inv[l] > 0.0f) {
                    weight[l] = span_overlap(lane_a[l], lane_b[l], lo, hi) * lane_inv[l];
                } else {
                    // The chip is the material between this edge point and the previous tooth's pass,
                    // h above it: no more than the ray holds there.
                    const float zl = lane_z[l];
                    const int inside = any(isgreaterequal((float4)(zl), lo) & isless((float4)(zl), hi));
                    lane_h[l] = min(lane_h[l], span_overlap(zl, zl + lane_h[l], lo, hi));
                    weight[l] = inside && lane_h[l] > min_chip ? 1.0f : 0.0f;
                }
            }
            const float8 h_cut = vload8(0, lane_h);
            const float8 w = vload8(0, weight);
            const int8 m = isgreater(w, (float8)(0.0f));
            if (!any(m)) continue;
            // Engaged axial extent: the element span where it is fully engaged (flat-bottom points have
            // za = zb), the clipped span on the rare partly engaged lanes.
            const int8 partial = m & isless(w, (float8)(FULL_WEIGHT));
            float8 elo = select((float8)(1e30f), za, m), ehi = select((float8)(-1e30f), zb, m);
            if (any(partial)) {
                float clip_lo[8], clip_hi[8];
                int lane_partial[8];
                vstore8(elo, 0, clip_lo);
                vstore8(ehi, 0, clip_hi);
                vstore8(partial, 0, lane_partial);
                for (int l = 0; l < 8; ++l) {
                    if (!lane_partial[l]) continue;
                    float4 lo, hi;
                    material_at(cells, walls, base_lo, base_hi, cell[l], lane_u[l], lane_v[l], nx, ny, cell_mm,
                                wall_tol, &lo, &hi);
                    span_clip(lane_a[l], lane_b[l], lo, hi, &clip_lo[l], &clip_hi[l]);
                }
                elo = vload8(0, clip_lo);
                ehi = vload8(0, clip_hi);
            }
            const float8 db = vload8(0, el_db + c) * w;
            // The cutting law (force_model/cutting_law.hpp; the twin's element_force).
            const float8 dFt = select((float8)(0.0f), (Ktc * h_cut + Kte) * db, m);
            const float8 dFr = select((float8)(0.0f), (Krc * h_cut + Kre) * db, m);
            const float8 dFa = select((float8)(0.0f), (Kac * h_cut + Kae) * db, m);
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
            chip = max(chip, select((float8)(0.0f), h_cut, m));
            const float8 q = r * (cu * px + su * py);
            qmin = min(qmin, select((float8)(1e30f), q, m));
            qmax = max(qmax, select((float8)(-1e30f), q, m));
            zmin = min(zmin, elo - tz);
            zmax = max(zmax, ehi - tz);
            engaged -= m;
        }
    }
    __global float* o = out + 12 * i;
    if (!any(engaged != 0)) {
        for (int k = 0; k < 12; ++k) o[k] = 0.0f;
        return;
    }
    const float4 F4x = Fx.lo + Fx.hi, F4y = Fy.lo + Fy.hi, F4z = Fz.lo + Fz.hi;
    const float4 T4 = T.lo + T.hi, M4x = Mx.lo + Mx.hi, M4y = My.lo + My.hi;
    const float4 c4 = max(chip.lo, chip.hi), qn4 = min(qmin.lo, qmin.hi), qx4 = max(qmax.lo, qmax.hi);
    const float4 zn4 = min(zmin.lo, zmin.hi), zx4 = max(zmax.lo, zmax.hi);
    const int4 n4 = engaged.lo + engaged.hi;
    const int n = n4.x + n4.y + n4.z + n4.w;
    o[0] = F4x.x + F4x.y + F4x.z + F4x.w;
    o[1] = F4y.x + F4y.y + F4y.z + F4y.w;
    o[2] = F4z.x + F4z.y + F4z.z + F4z.w;
    o[3] = T4.x + T4.y + T4.z + T4.w;
    o[4] = M4x.x + M4x.y + M4x.z + M4x.w;
    o[5] = M4y.x + M4y.y + M4y.z + M4y.w;
    o[6] = max(max(c4.x, c4.y), max(c4.z, c4.w));
    o[7] = n ? min(min(qn4.x, qn4.y), min(qn4.z, qn4.w)) : 0.0f;
    o[8] = n ? max(max(qx4.x, qx4.y), max(qx4.z, qx4.w)) : 0.0f;
    o[9] = n ? min(min(zn4.x, zn4.y), min(zn4.z, zn4.w)) : 0.0f;
    o[10] = n ? max(max(zx4.x, zx4.y), max(zx4.z, zx4.w)) : 0.0f;
    o[11] = (float)n;
}
