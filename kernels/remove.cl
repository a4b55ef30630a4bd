// Swept-volume removal: one work item per dexel ray in the batch's cell rectangle. For each straight
// segment of the tip path it finds where the tool's lower surface passes lowest over the ray and
// the top of the cutting part, then subtracts that interval from the ray. Twin: sweep_twin.
//
// segs:  6 floats per segment: a x, y, z, b x, y, z (tool tip)
// lower: lower surface height above the tip at radius d = k * radius / (n_lower - 1)
// cells: 8 floats per ray (lo[4], hi[4]), each XOR-ed with base[8] (RayCodec); a ray is written back
//        only when it changes, so the pages of rays the tool misses stay untouched
// walls: 2 float4 per ray (Wall: clearance XOR-ed with NO_WALL's bits, z_from, normal x, y): of the
//        side walls within `band` of the ray's centre, first the one with the smallest signed
//        clearance (the sweep that takes the centre in deepest, else the nearest), then the one that
//        starts lowest (z_from; within `band` of height, the smaller clearance), empty when that is
//        the first one; each written only when it changes
// out:   per ray: removed length, new top
// all_changed: per ray (from out_first on, like out), 1 where the ray was written, else 0 (for
//        refresh_tops)
#define K 4
#define EMPTY_LO 1e30f
#define EMPTY_HI -1e30f
#define SLIVER 1e-4f   // kSliverMm in engine_kernels.hpp
#define NO_WALL 1e30f  // kNoWall
#define WALL_MARK 2e30f  // kWallMark

// Whether wall a (clearance, z_from, normal) displaces b in a ray's second slot: the lower z_from,
// and within z_tol of height the smaller clearance. Twin: lower_wall.
bool lower_wall(const float4 a, const float4 b, const float z_tol) {
    if (!(b.x < NO_WALL)) return true;
    if (fabs(a.y - b.y) > z_tol) return a.y < b.y;
    return a.x < b.x;
}

float4 load_wall(__global const float4* walls, const int slot) {
    float4 w = walls[slot];
    w.x = as_float(as_uint(w.x) ^ as_uint(NO_WALL));
    return w;
}

void store_wall(__global float4* walls, const int slot, const float4 w) {
    walls[slot] = (float4)(as_float(as_uint(w.x) ^ as_uint(NO_WALL)), w.yzw);
}

bool same_wall(const float4 a, const float4 b) { return all(as_uint4(a) == as_uint4(b)); }

float lower_at(__global const float* lower, const int n_lower, const float radius, const float d) {
    const float u = clamp(d / radius, 0.0f, 1.0f) * (float)(n_lower - 1);
    const int i = min((int)u, n_lower - 2);
    const float w = u - (float)i;
    return lower[i] * (1.0f - w) + lower[i + 1] * w;
}

float height_at(const float A, const float B, const float C, const float az, const float uz, const float t,
                __global const float* lower, const int n_lower, const float radius) {
    const float d = sqrt(fmax(0.0f, A * t * t + B * t + C));
    return az + uz * t + lower_at(lower, n_lower, radius, d);
}

__kernel void remove_sweep(__global uint* cells, __constant uint* base, const int nx, const float x0, const float y0,
                           const float cell, const int i0, const int j0, const int width, const int height,
                           __global const float* all_segs, const int seg_first, const int n_segs,
                           __global const float* lower, const int n_lower, const float radius,
                           const float cut_length, __global float2* all_out, const int out_first,
                           __global float4* walls, const float band, __global uchar* all_changed) {
    const int g = get_global_id(0);
    if (g >= width * height) return;
    __global const float* segs = all_segs + 6 * seg_first;
    __global float2* out = all_out + out_first;
    const int ii = g % width, jj = g / width;
    const int i = i0 + ii, j = j0 + jj;
    const float cx = x0 + ((float)i + 0.5f) * cell, cy = y0 + ((float)j + 0.5f) * cell;
    const float R2 = radius * radius;
    const int index = j * nx + i;
    // This call's wall candidates (deepest, lowest); the stored walls are read only when there are
    // any, so the pages of rays far from every wall stay untouched.
    const float4 none = (float4)(NO_WALL, 0.0f, 0.0f, 0.0f);
    float4 wall = none, low = none;
    const float lower_r = lower[n_lower - 1];
    const float band_lo2 = fmax(0.0f, radius - band) * fmax(0.0f, radius - band), band_hi2 = (radius + band) * (radius + band);
    float zb = INFINITY, zt = -INFINITY;
    for (int s = 0; s < n_segs; ++s) {
        __global const float* sg = segs + 6 * s;
        const float ux = sg[3] - sg[0], uy = sg[4] - sg[1], uz = sg[5] - sg[2];
        const float wx = sg[0] - cx, wy = sg[1] - cy;
        const float A = ux * ux + uy * uy, B = 2.0f * (ux * wx + uy * wy), C = wx * wx + wy * wy;
        const float tc = A < 1e-18f ? 0.0f : clamp(-B / (2.0f * A), 0.0f, 1.0f);   // closest approach
        const float d2 = fmax(0.0f, (A * tc + B) * tc + C);
        if (d2 > band_lo2 && d2 < band_hi2) {
            const float d = sqrt(d2);
            const float4 side = (float4)(d - radius, sg[2] + uz * tc + lower_r, -(wx + ux * tc) / d, -(wy + uy * tc) / d);
            if (d > 1e-9f) {
                if (side.x < wall.x) wall = side;
                if (lower_wall(side, low, band)) low = side;
            }
        }
        if (d2 > R2) continue;
        float t0 = 0.0f, t1 = 1.0f;
        if (A >= 1e-18f) {
            const float sq = sqrt(fmax(0.0f, B * B - 4.0f * A * (C - R2)));
            t0 = fmax(0.0f, (-B - sq) / (2.0f * A));
            t1 = fmin(1.0f, (-B + sq) / (2.0f * A));
        }
        float best;
        if (fabs(uz) < 1e-12f) {
            best = height_at(A, B, C, sg[2], uz, tc, lower, n_lower, radius);
        } else {
            const float inv_phi = 0.618034f;
            float lo = t0, hi = t1;
            float m1 = hi - inv_phi * (hi - lo), m2 = lo + inv_phi * (hi - lo);
            float h1 = height_at(A, B, C, sg[2], uz, m1, lower, n_lower, radius);
            float h2 = height_at(A, B, C, sg[2], uz, m2, lower, n_lower, radius);
            for (int it = 0; it < 24; ++it) {
                if (h1 < h2) {
                    hi = m2; m2 = m1; h2 = h1; m1 = hi - inv_phi * (hi - lo);
                    h1 = height_at(A, B, C, sg[2], uz, m1, lower, n_lower, radius);
                } else {
                    lo = m1; m1 = m2; h1 = h2; m2 = lo + inv_phi * (hi - lo);
                    h2 = height_at(A, B, C, sg[2], uz, m2, lower, n_lower, radius);
                }
            }
            best = fmin(fmin(h1, h2), fmin(height_at(A, B, C, sg[2], uz, t0, lower, n_lower, radius),
                                           height_at(A, B, C, sg[2], uz, t1, lower, n_lower, radius)));
        }
        zb = fmin(zb, best);
        zt = fmax(zt, fmax(sg[2] + uz * t0, sg[2] + uz * t1) + cut_length);
    }
    __global uint* stored = cells + 8 * index;
    float ray[2 * K];
    for (int k = 0; k < 2 * K; ++k) ray[k] = as_float(stored[k] ^ base[k]);
    // A ray with a wall carries the mark in its last slot (kWallMark), if that slot is free. The
    // stored wall is read only for a marked ray: an unmarked one has none that engagement would use,
    // and writing a page without reading it first spares the copy-on-write of a zero page, which
    // costs every thread of the process a TLB flush.
    bool marked = ray[K - 1] == WALL_MARK;
    if (wall.x < NO_WALL) {
        __global float4* slots = walls + 2 * index;
        const float4 had = marked ? load_wall(slots, 0) : none, had_low = marked ? load_wall(slots, 1) : none;
        const float4 new_wall = wall.x < had.x ? wall : had;
        const float4 low_before = had_low.x < NO_WALL ? had_low : had;
        float4 new_low = lower_wall(low, low_before, band) ? low : low_before;
        if (same_wall(new_low, new_wall)) new_low = none;
        if (!same_wall(new_wall, had)) store_wall(slots, 0, new_wall);
        if (!same_wall(new_low, had_low)) store_wall(slots, 1, new_low);
        marked = true;
    }
    float before = 0.0f, after = 0.0f, top = EMPTY_HI;
    float plo[K + 1], phi[K + 1];
    int n = 0;
    for (int k = 0; k < K; ++k) {
        const float lo = ray[k], hi = ray[K + k];
        if (!(hi > lo)) continue;
        before += hi - lo;
        if (!(zb < zt) || zt <= lo || zb >= hi) {
            plo[n] = lo; phi[n] = hi; ++n;
            continue;
        }
        if (zb - lo > SLIVER) { plo[n] = lo; phi[n] = zb; ++n; }
        if (hi - zt > SLIVER) { plo[n] = zt; phi[n] = hi; ++n; }
    }
    // Pieces come out ordered (input sorted, each split yields lower piece first).
    if (n > K) {
        int narrowest = 0;
        for (int k = 1; k + 1 < n; ++k)
            if (plo[k + 1] - phi[k] < plo[narrowest + 1] - phi[narrowest]) narrowest = k;
        phi[narrowest] = phi[narrowest + 1];
        for (int k = narrowest + 1; k + 1 < n; ++k) { plo[k] = plo[k + 1]; phi[k] = phi[k + 1]; }
        --n;
    }
    float out_ray[2 * K];
    for (int k = 0; k < K; ++k) {
        out_ray[k] = k < n ? plo[k] : EMPTY_LO;
        out_ray[K + k] = k < n ? phi[k] : EMPTY_HI;
        if (k < n) { after += phi[k] - plo[k]; top = fmax(top, phi[k]); }
    }
    if (marked && n < K) out_ray[K - 1] = WALL_MARK;
    bool changed = false;
    for (int k = 0; k < 2 * K; ++k) changed |= as_uint(out_ray[k]) != as_uint(ray[k]);
    // Unchanged rays are not written back: their pages stay untouched.
    if (changed)
        for (int k = 0; k < 2 * K; ++k) stored[k] = as_uint(out_ray[k]) ^ base[k];
    out[g] = (float2)(before - after, top);
    all_changed[out_first + g] = changed ? 1 : 0;
}

// The ray's top (its highest interval end, EMPTY_HI when it holds none), and whether it carries the
// wall mark.
float ray_top_at(__global const uint* cells, __constant uint* base, const int index, bool* marked) {
    const uint8 stored = vload8(index, cells) ^ vload8(0, base);
    const float4 lo = as_float4(stored.lo), hi = as_float4(stored.hi);
    const float4 top = select((float4)(EMPTY_HI), hi, isgreater(hi, lo));
    *marked = lo.w == WALL_MARK;
    return max(max(top.x, top.y), max(top.z, top.w));
}

// The highest top of the ray (i, j) and its eight neighbours (on the grid).
float neighbours_top(__global const uint* cells, __constant uint* base, const int nx, const int ny, const int i,
                     const int j) {
    float top = EMPTY_HI;
    for (int b = max(j - 1, 0); b <= min(j + 1, ny - 1); ++b)
        for (int a = max(i - 1, 0); a <= min(i + 1, nx - 1); ++a) {
            bool unused = false;
            top = max(top, ray_top_at(cells, base, b * nx + a, &unused));
        }
    return top;
}

// The per-ray tops engage.cl skips lookups by, refreshed after a flush's removal calls: a ray's
// top, or for a ray with the wall mark the highest top of it and its eight neighbours, since its
// material may be that of the ray one cell across its wall (engage.cl's material_at). Bits XOR-ed
// with top_base's, so a ray never cut is 0; written only where the value changes. A ray's value
// depends on its own ray and, with the mark, its neighbours: of each call's rectangle and one ray
// around it, only the rays the call wrote and the marked rays next to one are computed. A kernel
// of its own, queued after the calls, because it reads neighbours that remove_sweep may be
// writing. Twin: refresh_tops_twin (which computes every ray of the rectangle it is given).
//
// calls: from table_first on in the segments' buffer (it rides along with them), per call 6 ints:
//        its rectangle i0, j0, width, height (on the grid), where its flags start in all_changed (row
//        by row), its first work item; then the number of work items (one per ray of each rectangle
//        grown by one ray and clipped to the grid). With no calls: every ray of the rectangle
//        rect_width x rect_height from (rect_i0, rect_j0) (after a window's lead-in, walked for its
//        removal alone, over what it may have changed), one work item each; the table and the flags
//        are not read.
__kernel void refresh_tops(__global const uint* cells, __constant uint* base, const int nx, const int ny,
                           __global const float* all_segs, const int table_first, const int n_calls,
                           __global const uchar* all_changed, const int rect_i0, const int rect_j0,
                           const int rect_width, const int rect_height, __global uint* tops, const uint top_base) {
    const int g = get_global_id(0);
    if (n_calls == 0) {
        if (g >= rect_width * rect_height) return;
        const int i = rect_i0 + g % rect_width, j = rect_j0 + g / rect_width;
        bool marked = false;
        float top = ray_top_at(cells, base, j * nx + i, &marked);
        if (marked) top = max(top, neighbours_top(cells, base, nx, ny, i, j));
        const uint value = as_uint(top) ^ top_base;
        if (tops[j * nx + i] != value) tops[j * nx + i] = value;
        return;
    }
    __global const int* calls = (__global const int*)(all_segs + table_first);
    if (g >= calls[6 * n_calls]) return;
    int r = 0;
    while (r + 1 < n_calls && g >= calls[6 * (r + 1) + 5]) ++r;
    __global const int* call = calls + 6 * r;
    const int i0 = call[0], j0 = call[1], width = call[2], height = call[3];
    __global const uchar* changed = all_changed + call[4];
    const int gi0 = max(i0 - 1, 0), gj0 = max(j0 - 1, 0), grown_width = min(i0 + width + 1, nx) - gi0;
    const int i = gi0 + (g - call[5]) % grown_width, j = gj0 + (g - call[5]) / grown_width;
    const bool inside = i >= i0 && i < i0 + width && j >= j0 && j < j0 + height;
    // A ray the call wrote takes its new value. One it did not write changes only when it has the
    // wall mark (read first: one word) and a neighbour was written.
    if (!(inside && changed[(j - j0) * width + (i - i0)])) {
        if (as_float(cells[8 * (j * nx + i) + K - 1] ^ base[K - 1]) != WALL_MARK) return;
        bool near_change = false;
        for (int b = max(j - 1, j0); b <= min(j + 1, j0 + height - 1); ++b)
            for (int a = max(i - 1, i0); a <= min(i + 1, i0 + width - 1); ++a)
                near_change |= changed[(b - j0) * width + (a - i0)] != 0;
        if (!near_change) return;
    }
    bool marked = false;
    float top = ray_top_at(cells, base, j * nx + i, &marked);
    if (marked) top = max(top, neighbours_top(cells, base, nx, ny, i, j));
    const uint value = as_uint(top) ^ top_base;
    if (tops[j * nx + i] != value) tops[j * nx + i] = value;
}
