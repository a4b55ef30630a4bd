// The multi-direction (tri-dexel) stock on the device: engagement of tools at any orientation
// (engage_poses) and removal of a convex tool solid swept along chords (sweep_chords). Twins:
// engage_tri_dexel and sweep_tri_dexel in tri_dexel.cpp, which this file follows line for line.
//
// Built without -cl-fast-relaxed-math (opencl_runtime.cpp): misses and empty bounds are infinities,
// compared and kept exactly as the twins keep them, and fmin/fmax (min/max are undefined for them).
//
// Double precision throughout, unlike engage.cl and remove.cl. The removal intersects lines with
// cones at any angle: a ray almost along a cone's surface makes the quadratic's leading term a
// difference of nearly equal squares, which float loses. The twins are double, so this file gives
// their results to a few ulps of the transcendental functions. Every device the engine targets has
// cl_khr_fp64 (PoCL on x86; data-centre GPUs run it at half the float rate); the host refuses a
// device without it before building this file.
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

#define K 4                 // kDexelIntervals
#define SLIVER 1e-4         // kSliverMm
#define EMPTY_LO 1e30f
#define EMPTY_HI -1e30f
#define INF_D (1.0 / 0.0)

// ---- The stock ------------------------------------------------------------------------------------
// grid (double): cell_mm, then per family f (rays along axis f): u0_mm, v0_mm, with u = (f+1)%3,
//                v = (f+2)%3
// dims (int):    per family: nu, nv
// rays:          one buffer per family, 8 floats per ray (lo[4], hi[4], unencoded), row-major j*nu+i

bool ray_contains(__global const float* ray, const double z) {
    for (int k = 0; k < K; ++k)
        if (z >= (double)ray[k] && z < (double)ray[K + k]) return true;
    return false;
}

double ray_overlap(__global const float* ray, const double a_mm, const double b_mm, double* lo_mm, double* hi_mm) {
    double len = 0;
    *lo_mm = INF_D;
    *hi_mm = -INF_D;
    for (int k = 0; k < K; ++k) {
        const double a = fmax(a_mm, (double)ray[k]), b = fmin(b_mm, (double)ray[K + k]);
        if (!(b - a > SLIVER)) continue;
        len += b - a;
        *lo_mm = fmin(*lo_mm, a);
        *hi_mm = fmax(*hi_mm, b);
    }
    return len;
}

double ray_length(__global const float* ray) {
    double len = 0;
    for (int k = 0; k < K; ++k)
        if (ray[K + k] > ray[k]) len += (double)ray[K + k] - (double)ray[k];
    return len;
}

// Removes [a, b) from the ray; returns the length removed. A split that would need a fifth interval
// closes the narrowest gap. Twin: subtract_interval (twins.cpp).
double subtract_interval(__global float* ray, const double a_mm, const double b_mm) {
    double plo[K + 1], phi[K + 1];
    int n = 0;
    const double before = ray_length(ray);
    for (int k = 0; k < K; ++k) {
        const double lo = ray[k], hi = ray[K + k];
        if (!(hi > lo)) continue;
        if (b_mm <= lo || a_mm >= hi) {
            plo[n] = lo;
            phi[n++] = hi;
            continue;
        }
        if (a_mm - lo > SLIVER) {
            plo[n] = lo;
            phi[n++] = a_mm;
        }
        if (hi - b_mm > SLIVER) {
            plo[n] = b_mm;
            phi[n++] = hi;
        }
    }
    if (n > K) {
        int narrowest = 0;
        for (int k = 1; k + 1 < n; ++k)
            if (plo[k + 1] - phi[k] < plo[narrowest + 1] - phi[narrowest]) narrowest = k;
        phi[narrowest] = phi[narrowest + 1];
        for (int k = narrowest + 1; k + 1 < n; ++k) {
            plo[k] = plo[k + 1];
            phi[k] = phi[k + 1];
        }
        --n;
    }
    for (int k = 0; k < K; ++k) {
        ray[k] = k < n ? (float)plo[k] : EMPTY_LO;
        ray[K + k] = k < n ? (float)phi[k] : EMPTY_HI;
    }
    return before - ray_length(ray);
}

typedef struct {
    __global const float* rays[3];
} Families;

// The ray of family f nearest the point (its cell), or 0 off the family's grid.
__global const float* nearest_ray(const Families* fam, __constant double* grid, __constant int* dims, const int f,
                                  const double3 p) {
    const double pa[3] = {p.x, p.y, p.z};
    const int u = (f + 1) % 3, v = (f + 2) % 3;
    const double cell = grid[0];
    const double fu = (pa[u] - grid[1 + 2 * f]) / cell, fv = (pa[v] - grid[2 + 2 * f]) / cell;
    const int nu = dims[2 * f], nv = dims[2 * f + 1];
    if (!(fu >= 0 && fv >= 0 && fu < nu && fv < nv)) return 0;
    return fam->rays[f] + (size_t)(((long)fv * nu + (long)fu) * 8);
}

// Whether the point is in material as told by the family whose ray has a boundary nearest the point
// along it. Twin: tri_dexel_inside.
bool tri_dexel_inside(const Families* fam, __constant double* grid, __constant int* dims, const double3 p) {
    const double pa[3] = {p.x, p.y, p.z};
    bool inside = false;
    double nearest = INF_D;
    for (int f = 0; f < 3; ++f) {
        double boundary = INF_D;
        bool in = false;
        __global const float* ray = nearest_ray(fam, grid, dims, f, p);
        if (ray) {
            for (int k = 0; k < K; ++k)
                if (ray[K + k] > ray[k])
                    boundary = fmin(boundary, fmin(fabs(pa[f] - (double)ray[k]), fabs(pa[f] - (double)ray[K + k])));
            in = ray_contains(ray, pa[f]);
        }
        if (f == 0 || boundary < nearest) {
            nearest = boundary;
            inside = in;
        }
    }
    return inside;
}

// Signed distance along the ray from x to the ray's nearest interval end: positive in material,
// negative outside; -inf for a ray that holds nothing. Twin: ray_signed_mm.
double ray_signed_mm(__global const float* ray, const double x) {
    double d = INF_D;
    for (int k = 0; k < K; ++k)
        if (ray[K + k] > ray[k]) d = fmin(d, fmin(fabs(x - (double)ray[k]), fabs(x - (double)ray[K + k])));
    return ray_contains(ray, x) ? d : -d;
}

// Whether the point is in material, placed to a fraction of a cell: the signed distance along each
// family's rays, blended bilinearly from the four rays around the point where all four have a
// boundary within two cells; the family with the least blended distance tells; where none blends,
// as tri_dexel_inside. Twin: inside_sub_cell (tri_dexel.cpp says why).
bool inside_sub_cell(const Families* fam, __constant double* grid, __constant int* dims, const double3 p) {
    const double pa[3] = {p.x, p.y, p.z};
    const double g = grid[0], reach_mm = 2 * g;
    double best_mm = INF_D;
    bool inside = false;
    for (int f = 0; f < 3; ++f) {
        const int u = (f + 1) % 3, v = (f + 2) % 3;
        const int nu = dims[2 * f], nv = dims[2 * f + 1];
        const double fu = (pa[u] - grid[1 + 2 * f]) / g - 0.5, fv = (pa[v] - grid[2 + 2 * f]) / g - 0.5;
        const double i0 = floor(fu), j0 = floor(fv);
        if (!(i0 >= 0 && j0 >= 0 && i0 + 1 < nu && j0 + 1 < nv)) continue;
        __global const float* r00 = fam->rays[f] + (size_t)(((long)j0 * nu + (long)i0) * 8);
        const double x = pa[f];
        const double s00 = ray_signed_mm(r00, x);
        if (!(fabs(s00) < reach_mm)) continue;
        const double s10 = ray_signed_mm(r00 + 8, x);
        if (!(fabs(s10) < reach_mm)) continue;
        const double s01 = ray_signed_mm(r00 + (size_t)nu * 8, x);
        if (!(fabs(s01) < reach_mm)) continue;
        const double s11 = ray_signed_mm(r00 + (size_t)(nu + 1) * 8, x);
        if (!(fabs(s11) < reach_mm)) continue;
        const double wu = fu - i0, wv = fv - j0;
        const double s = (1 - wv) * ((1 - wu) * s00 + wu * s10) + wv * ((1 - wu) * s01 + wu * s11);
        if (fabs(s) < best_mm) {
            best_mm = fabs(s);
            inside = s > 0;
        }
    }
    return best_mm < INF_D ? inside : tri_dexel_inside(fam, grid, dims, p);
}

// rot: 9 doubles, row-major (rot[r][c]; columns are the tool's axes in stock coordinates).
double3 turn(const double* rot, const double3 v) {
    return (double3)(rot[0] * v.x + rot[1] * v.y + rot[2] * v.z, rot[3] * v.x + rot[4] * v.y + rot[5] * v.z,
                     rot[6] * v.x + rot[7] * v.y + rot[8] * v.z);
}

double3 to_tool(const double* rot, const double3 v) {
    return (double3)(rot[0] * v.x + rot[3] * v.y + rot[6] * v.z, rot[1] * v.x + rot[4] * v.y + rot[7] * v.z,
                     rot[2] * v.x + rot[5] * v.y + rot[8] * v.z);
}

// ---- Engagement -----------------------------------------------------------------------------------
// One work item per step. Twin: engage_tri_dexel.
// steps: 20 doubles per step: tip x, y, z; rot[9]; feed per tooth x, y, z (tool frame); turn per
//        tooth x, y, z (tool frame); theta; unused
// elems: 8 doubles per element: r, z, nr, nz, db, z_lo, z_hi, lag
// coef:  Ktc, Krc, Kac, Kte, Kre, Kae, holder face height, minimum chip thickness
// out:   12 floats per step (StepResult)
__kernel void engage_poses(const int n_steps, __global const double* steps, const double spin,
                           __global const double* elems, const int n_flutes, const int element_end,
                           __constant double* coef, __constant double* grid, __constant int* dims,
                           __global const float* rays_x, __global const float* rays_y, __global const float* rays_z,
                           __global float* out) {
    const int i = get_global_id(0);
    if (i >= n_steps) return;
    Families fam;
    fam.rays[0] = rays_x;
    fam.rays[1] = rays_y;
    fam.rays[2] = rays_z;
    __global const double* st = steps + 20 * (size_t)i;
    const double3 tip = (double3)(st[0], st[1], st[2]);
    double rot[9];
    for (int k = 0; k < 9; ++k) rot[k] = st[3 + k];
    const double3 sfeed = (double3)(st[12], st[13], st[14]);
    const double3 w = (double3)(st[15], st[16], st[17]);
    const double theta = st[18];
    const double Ktc = coef[0], Krc = coef[1], Kac = coef[2], Kte = coef[3], Kre = coef[4], Kae = coef[5];
    const double face_z = coef[6], min_chip = coef[7];
    const double pitch = 2 * M_PI / n_flutes;
    // The family most nearly along the tool axis (best_family).
    const double axis[3] = {rot[2], rot[5], rot[8]};
    int f_axis = 2;
    for (int f = 0; f < 3; ++f)
        if (fabs(axis[f]) > fabs(axis[f_axis])) f_axis = f;
    const double fxy = hypot(sfeed.x, sfeed.y);
    const double px = fxy > 1e-12 ? -sfeed.y / fxy : 1.0, py = fxy > 1e-12 ? sfeed.x / fxy : 0.0;
    double Fx = 0, Fy = 0, Fz = 0, T = 0, Mx = 0, My = 0, chip = 0;
    double qmin = 1e30, qmax = -1e30, zmin = 1e30, zmax = -1e30;
    int engaged = 0;
    for (int j = 0; j < n_flutes; ++j) {
        for (int e = 0; e < element_end; ++e) {
            __global const double* el = elems + 8 * e;
            const double r = el[0], ez_mm = el[1], nr = el[2], nz = el[3], db0 = el[4], zlo = el[5], zhi = el[6];
            const double alpha = M_PI / 2 - theta - j * pitch + spin * el[7];
            const double cu = cos(alpha), su = sin(alpha);
            const double3 r_tool = (double3)(r * cu, r * su, ez_mm);
            const double3 feed = (double3)(sfeed.x + w.y * r_tool.z - w.z * r_tool.y, sfeed.y + w.z * r_tool.x - w.x * r_tool.z,
                                           sfeed.z + w.x * r_tool.y - w.y * r_tool.x);
            const double h = nr * (feed.x * cu + feed.y * su) + nz * feed.z;
            if (h <= min_chip) continue;
            const double3 P = tip + turn(rot, (double3)(r_tool.x, r_tool.y, ez_mm));
            const double span = zhi - zlo;
            double weight = 0, h_cut = h, clip_lo = ez_mm, clip_hi = ez_mm;
            if (span > 0) {
                const double3 a = tip + turn(rot, (double3)(r_tool.x, r_tool.y, zlo));
                const double3 b = tip + turn(rot, (double3)(r_tool.x, r_tool.y, zhi));
                const double aa[3] = {a.x, a.y, a.z}, ba[3] = {b.x, b.y, b.z};
                __global const float* ray = nearest_ray(&fam, grid, dims, f_axis, P);
                const double lo = fmin(aa[f_axis], ba[f_axis]), hi = fmax(aa[f_axis], ba[f_axis]);
                double m_lo = 0, m_hi = 0;
                const double overlap = ray && hi > lo ? ray_overlap(ray, lo, hi, &m_lo, &m_hi) : 0;
                if (overlap > 0) {
                    const bool rising = ba[f_axis] >= aa[f_axis];
                    const double t_lo = (m_lo - lo) / (hi - lo), t_hi = (m_hi - lo) / (hi - lo);
                    clip_lo = rising ? zlo + t_lo * span : zhi - t_hi * span;
                    clip_hi = rising ? zlo + t_hi * span : zhi - t_lo * span;
                    const double3 mid = tip + turn(rot, (double3)(r_tool.x, r_tool.y, 0.5 * (clip_lo + clip_hi)));
                    if (inside_sub_cell(&fam, grid, dims, mid)) weight = overlap / (hi - lo);
                } else if (inside_sub_cell(&fam, grid, dims, P)) {
                    weight = 1;
                    clip_lo = zlo;
                    clip_hi = zhi;
                }
            } else if (inside_sub_cell(&fam, grid, dims, P)) {
                // The chip is the material between this point and the previous tooth's pass.
                const double3 nW = turn(rot, (double3)(nr * cu, nr * su, nz));
                int in = 0;
                for (int q = 1; q <= 10; ++q) {
                    const double d = -h * (q - 0.5) / 10;
                    in += inside_sub_cell(&fam, grid, dims, P + d * nW) ? 1 : 0;
                }
                h_cut = h * in / 10;
                if (h_cut > min_chip) weight = 1;
            }
            if (weight <= 0) continue;
            const double db = db0 * weight;
            const double dFt = (Ktc * h_cut + Kte) * db, dFr = (Krc * h_cut + Kre) * db, dFa = (Kac * h_cut + Kae) * db;
            const double normal = dFr * nr + dFa * nz;
            const double ex = -spin * dFt * su - normal * cu;
            const double ey = spin * dFt * cu - normal * su;
            const double ez = -dFr * nz + dFa * nr;
            Fx += ex;
            Fy += ey;
            Fz += ez;
            T += r * dFt;
            const double lz = ez_mm - face_z;
            Mx += r * su * ez - lz * ey;
            My += lz * ex - r * cu * ez;
            chip = fmax(chip, h_cut);
            const double q = r * (cu * px + su * py);
            qmin = fmin(qmin, q);
            qmax = fmax(qmax, q);
            zmin = fmin(zmin, clip_lo);
            zmax = fmax(zmax, clip_hi);
            ++engaged;
        }
    }
    const double3 F = turn(rot, (double3)(Fx, Fy, Fz));
    __global float* o = out + 12 * (size_t)i;
    o[0] = (float)F.x;
    o[1] = (float)F.y;
    o[2] = (float)F.z;
    o[3] = (float)T;
    o[4] = (float)Mx;
    o[5] = (float)My;
    o[6] = (float)chip;
    o[7] = engaged ? (float)qmin : 0.0f;
    o[8] = engaged ? (float)qmax : 0.0f;
    o[9] = engaged ? (float)zmin : 0.0f;
    o[10] = engaged ? (float)zmax : 0.0f;
    o[11] = (float)engaged;
}

// ---- Removal --------------------------------------------------------------------------------------
// Narrows [lo, hi] to where the line p + t u lies inside the cone rho <= a + b z, given that
// a + b z >= 0 on the stretch; false when nothing is left. Twin: clip_to_cone.
bool clip_to_cone(const double a, const double b, const double3 p, const double3 u, const double uxy, double* lo,
                  double* hi) {
    const double w0 = a + b * p.z, w1 = b * u.z;
    const double A = uxy - w1 * w1;
    const double B = 2 * (p.x * u.x + p.y * u.y - w0 * w1);
    const double C = p.x * p.x + p.y * p.y - w0 * w0;
    if (fabs(A) <= 1e-12 * (uxy + w1 * w1)) {
        if (fabs(B) < 1e-300) return C <= 0;
        if (B > 0)
            *hi = fmin(*hi, -C / B);
        else
            *lo = fmax(*lo, -C / B);
    } else {
        const double disc = B * B - 4 * A * C;
        // A > 0: inside between the roots. A < 0: inside outside them, two half-lines, of which only
        // one meets the slab's nappe; with no real root the whole line is inside the double cone.
        if (disc < 0) return A < 0 && *lo <= *hi;
        const double q = -0.5 * (B + copysign(sqrt(disc), B));
        const double ra = q / A, rb = q != 0 ? C / q : ra;
        const double r1 = fmin(ra, rb), r2 = fmax(ra, rb);
        if (A > 0) {
            *lo = fmax(*lo, r1);
            *hi = fmin(*hi, r2);
        } else {
            const double left = fmin(*hi, r1) - *lo, right = *hi - fmax(*lo, r2);
            if (left < 0 && right < 0) return false;
            if (left >= right)
                *hi = fmin(*hi, r1);
            else
                *lo = fmax(*lo, r2);
        }
    }
    return *lo <= *hi;
}

// The solid: the union of its pieces, piece k the cone rho <= a + b z over heights [z0, z1]
// (cones: a, b, z0, z1 per piece), tool frame. Twin: line_in_solid.
bool line_in_solid(__global const double* cones, const int n_cones, const double3 p, const double3 u, double* t_in,
                   double* t_out) {
    const double uxy = u.x * u.x + u.y * u.y;
    double lo = INF_D, hi = -INF_D;
    for (int c = 0; c < n_cones; ++c) {
        const double a = cones[4 * c], b = cones[4 * c + 1], z0 = cones[4 * c + 2], z1 = cones[4 * c + 3];
        double plo = -INF_D, phi = INF_D;
        if (fabs(u.z) < 1e-15) {
            if (p.z < z0 || p.z > z1) continue;
        } else {
            const double ta = (z0 - p.z) / u.z, tb = (z1 - p.z) / u.z;
            plo = fmin(ta, tb);
            phi = fmax(ta, tb);
        }
        if (!clip_to_cone(a, b, p, u, uxy, &plo, &phi)) continue;
        lo = fmin(lo, plo);
        hi = fmax(hi, phi);
    }
    if (!(lo <= hi && isfinite(lo) && isfinite(hi))) return false;
    *t_in = lo;
    *t_out = hi;
    return true;
}

typedef struct {
    __global const double* cones;
    int n_cones;
    double3 p0, ut, d;   // the line's point and direction and the chord, tool frame
} SweepLine;

// The line's entry (want_exit false) or minus its exit at chord position s; +inf where the line
// misses the solid there.
double probe(const SweepLine* L, const double s, const bool want_exit) {
    double a, b;
    if (!line_in_solid(L->cones, L->n_cones, L->p0 - s * L->d, L->ut, &a, &b)) return INF_D;
    return want_exit ? -b : a;
}

// Golden-section minimum of probe on [a, b] (convex where finite; a tie of two infinite probes
// keeps the anchor's side). Twin: golden_min.
double golden_min(const SweepLine* L, const bool want_exit, double a, double b, const double anchor, double best) {
    const double phi = 0.6180339887498949;
    double x1 = b - phi * (b - a), x2 = a + phi * (b - a);
    double f1 = probe(L, x1, want_exit), f2 = probe(L, x2, want_exit);
    for (int k = 0; k < 24; ++k) {
        const bool keep_left = f1 < f2 || (f1 == f2 && anchor <= x1);
        if (keep_left) {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - phi * (b - a);
            f1 = probe(L, x1, want_exit);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + phi * (b - a);
            f2 = probe(L, x2, want_exit);
        }
        best = fmin(best, fmin(f1, f2));
    }
    return fmin(best, fmin(f1, f2));
}

// One work item per ray of family f in the rectangle [i0, i0 + ni) x [j0, j0 + nj); it removes the
// sweep of every chord, in order, from its ray. Twin: sweep_tri_dexel.
// chords:  24 doubles per chord: from x, y, z; to x, y, z; rot[9]; box lo x, y, z; box hi x, y, z;
//          samples; unused, unused
// removed: per work item, the length removed from its ray
__kernel void sweep_chords(const int f, const int i0, const int j0, const int ni, const int nj,
                           __global const double* chords, const int n_chords, __global const double* cones,
                           const int n_cones, __constant double* grid,
                           __constant int* dims, __global float* rays, __global double* removed) {
    const int gi = get_global_id(0);
    if (gi >= ni * nj) return;
    const int i = i0 + gi % ni, j = j0 + gi / ni;
    const int u = (f + 1) % 3, v = (f + 2) % 3;
    const double g = grid[0], u0 = grid[1 + 2 * f], v0 = grid[2 + 2 * f];
    const int nu = dims[2 * f], nv = dims[2 * f + 1];
    __global float* ray = rays + (size_t)(((long)j * nu + i) * 8);
    double p[3];
    p[f] = 0;
    p[u] = u0 + (i + 0.5) * g;
    p[v] = v0 + (j + 0.5) * g;
    double dir[3] = {0, 0, 0};
    dir[f] = 1;
    double gone = 0;
    for (int c = 0; c < n_chords; ++c) {
        __global const double* ch = chords + 24 * (size_t)c;
        const double lo[3] = {ch[15], ch[16], ch[17]}, hi[3] = {ch[18], ch[19], ch[20]};
        const int ci0 = max(0, (int)floor((lo[u] - u0) / g - 0.5)), ci1 = min(nu - 1, (int)ceil((hi[u] - u0) / g - 0.5));
        const int cj0 = max(0, (int)floor((lo[v] - v0) / g - 0.5)), cj1 = min(nv - 1, (int)ceil((hi[v] - v0) / g - 0.5));
        if (i < ci0 || i > ci1 || j < cj0 || j > cj1) continue;
        double m_lo, m_hi;
        if (!(ray_overlap(ray, lo[f], hi[f], &m_lo, &m_hi) > 0)) continue;
        double rot[9];
        for (int k = 0; k < 9; ++k) rot[k] = ch[6 + k];
        const double3 from = (double3)(ch[0], ch[1], ch[2]), to = (double3)(ch[3], ch[4], ch[5]);
        SweepLine L;
        L.cones = cones;
        L.n_cones = n_cones;
        L.p0 = to_tool(rot, (double3)(p[0], p[1], p[2]) - from);
        L.ut = to_tool(rot, (double3)(dir[0], dir[1], dir[2]));
        L.d = to_tool(rot, to - from);
        const int samples = max((int)ch[21], 2);
        const double step = 1.0 / (samples - 1);
        int k_in = -1, k_out = -1;
        double best_in = INF_D, best_out = -INF_D;
        for (int k = 0; k < samples; ++k) {
            double a, b;
            if (!line_in_solid(cones, n_cones, L.p0 - (k * step) * L.d, L.ut, &a, &b)) continue;
            if (a < best_in) {
                best_in = a;
                k_in = k;
            }
            if (b > best_out) {
                best_out = b;
                k_out = k;
            }
        }
        if (k_in < 0) continue;
        const double s_in = k_in * step, s_out = k_out * step;
        // An end is refined only where the ray holds material beyond the sampled one (line_in_sweep).
        bool refine_in = false, refine_out = false;
        for (int q = 0; q < K; ++q)
            if (ray[K + q] > ray[q]) {
                refine_in = refine_in || (double)ray[q] < best_in;
                refine_out = refine_out || (double)ray[K + q] > best_out;
            }
        const double t0 =
            refine_in ? golden_min(&L, false, fmax(0.0, s_in - step), fmin(1.0, s_in + step), s_in, best_in) : best_in;
        const double t1 =
            refine_out ? -golden_min(&L, true, fmax(0.0, s_out - step), fmin(1.0, s_out + step), s_out, -best_out) : best_out;
        if (t1 - t0 > SLIVER) gone += subtract_interval(ray, t0, t1);
    }
    removed[gi] = gone;
}

// ---- Shank and holder ------------------------------------------------------------------------------
// The part of the line p + t u inside the cylinder rho <= r, z0 <= z <= z1 (tool frame): the solid's
// line test with one piece of slope 0. Twin: line_in_cylinder (tri_dexel_body.cpp).
bool line_in_cylinder(const double r, const double z0, const double z1, const double3 p, const double3 u, double* lo,
                      double* hi) {
    double plo = -INF_D, phi = INF_D;
    if (fabs(u.z) < 1e-15) {
        if (p.z < z0 || p.z > z1) return false;
    } else {
        const double ta = (z0 - p.z) / u.z, tb = (z1 - p.z) / u.z;
        plo = fmin(ta, tb);
        phi = fmax(ta, tb);
    }
    if (!clip_to_cone(r, 0.0, p, u, u.x * u.x + u.y * u.y, &plo, &phi)) return false;
    if (!(plo <= phi && isfinite(plo) && isfinite(phi))) return false;
    *lo = plo;
    *hi = phi;
    return true;
}

// Whether a material interval overlaps [lo, hi] by more than a micrometre (kContactOverlapMm).
bool body_overlaps(__global const float* ray, const double lo, const double hi) {
    for (int k = 0; k < K; ++k) {
        const double a = ray[k], b = ray[K + k];
        if (b > a && fmin(b, hi) - fmax(a, lo) > 1e-3) return true;
    }
    return false;
}

// Distance from q (tool frame) to the holder's solid cylinder. body: see body_rays.
double to_holder(__constant double* body, const double3 q) {
    const double rho = hypot(q.x, q.y);
    const double top = body[1] + body[2];
    const double dr = fmax(rho - body[4], 0.0);
    const double dz = fmax(fmax(body[1] - q.z, q.z - top), 0.0);
    return hypot(dr, dz);
}

// One work item per ray of family f in the rectangle [i0, i0 + ni) x [j0, j0 + nj): contact with the
// shank or the holder, else the holder's distance to the ray's nearest material within the shell.
// Twins: tri_dexel_body_clearance's loop over a family, ray_body_clearance.
// pose: tip x, y, z; rot[9]; the box's lo and hi along f
// body: flute length, stickout, holder length, shank radius, holder radius, shell (all mm)
// out:  2 doubles per work item: contact (1 or 0), clearance (infinity: none within the shell)
__kernel void body_rays(const int f, const int i0, const int j0, const int ni, const int nj, __constant double* pose,
                        __constant double* body, __constant double* grid, __constant int* dims,
                        __global const float* rays, __global double* out) {
    const int gi = get_global_id(0);
    if (gi >= ni * nj) return;
    const int i = i0 + gi % ni, j = j0 + gi / ni;
    const int u = (f + 1) % 3, v = (f + 2) % 3;
    const double g = grid[0], u0 = grid[1 + 2 * f], v0 = grid[2 + 2 * f];
    const int nu = dims[2 * f];
    __global const float* ray = rays + (size_t)(((long)j * nu + i) * 8);
    out[2 * gi] = 0;
    out[2 * gi + 1] = INF_D;
    const double box_lo = pose[12], box_hi = pose[13];
    bool near = false;
    for (int k = 0; k < K && !near; ++k)
        near = ray[K + k] > ray[k] && ray[K + k] >= box_lo && ray[k] <= box_hi;
    if (!near) return;
    double rot[9];
    for (int k = 0; k < 9; ++k) rot[k] = pose[3 + k];
    double w[3];
    w[f] = -pose[f];
    w[u] = u0 + (i + 0.5) * g - pose[u];
    w[v] = v0 + (j + 0.5) * g - pose[v];
    const double3 p = to_tool(rot, (double3)(w[0], w[1], w[2]));
    const double3 d = (double3)(rot[3 * f], rot[3 * f + 1], rot[3 * f + 2]);
    const double flute = body[0], stickout = body[1], top = body[1] + body[2];
    const double r_shank = body[3], r_holder = body[4], shell = body[5];
    double lo, hi;
    if (stickout > flute && line_in_cylinder(r_shank * 0.98, flute, stickout, p, d, &lo, &hi) && body_overlaps(ray, lo, hi)) {
        out[2 * gi] = 1;
        return;
    }
    if (line_in_cylinder(r_holder, stickout, top, p, d, &lo, &hi) && body_overlaps(ray, lo, hi)) {
        out[2 * gi] = 1;
        return;
    }
    if (!(shell > 0)) return;
    double g0, g1;
    if (!line_in_cylinder(r_holder + shell, stickout - shell, top + shell, p, d, &g0, &g1)) return;
    double best_all = INF_D;
    for (int k = 0; k < K; ++k) {
        const double s0 = fmax((double)ray[k], g0), s1 = fmin((double)ray[K + k], g1);
        if (!(s1 >= s0)) continue;
        // Convex along the line: the ends and a golden-section search between them.
        double best = fmin(to_holder(body, p + s0 * d), to_holder(body, p + s1 * d));
        const double phi = 0.6180339887498949;
        double a = s0, c = s1;
        double x1 = c - phi * (c - a), x2 = a + phi * (c - a);
        double f1 = to_holder(body, p + x1 * d), f2 = to_holder(body, p + x2 * d);
        for (int it = 0; it < 60 && c - a > 1e-9; ++it) {
            if (f1 <= f2) {
                c = x2;
                x2 = x1;
                f2 = f1;
                x1 = c - phi * (c - a);
                f1 = to_holder(body, p + x1 * d);
            } else {
                a = x1;
                x1 = x2;
                f1 = f2;
                x2 = a + phi * (c - a);
                f2 = to_holder(body, p + x2 * d);
            }
        }
        best = fmin(best, fmin(f1, f2));
        if (best <= shell) best_all = fmin(best_all, best);
    }
    out[2 * gi + 1] = best_all;
}
