/* reach.c -- the feasibility engine: every limit of STEWART_LIMITS at a pose in one call
   (stroke, joint cones, leg-to-leg clearance, obstacle clearance, cond(J), and with rates and
   accelerations the drives' leg speed, acceleration and rack force), batched over poses, and
   the travel along a direction (the largest step before the first limit). The limits' bounds
   are the packed reach vector's (stewart_table.h STEWART_REACH_PARAMS). */
#include <math.h>
#include "internal.h"

#define RP(k) reach[STEWART_R_##k]
#define N_PAIRS 15
/* Golden-section steps of a leg's closest approach to a box or cylinder: the interval shrinks
   by 0.618 a step, 64 steps leave 4e-14 of the leg. */
#define GOLDEN_STEPS 64
/* smax / hmax beyond MAX_MARCH / 64 is refused: travel's steps (at most hmax) are then at
   least smax / 156250 wherever no limit is near. */
#define MAX_MARCH 10000000.0
/* The most poses a travel's conservative advancement evaluates (a bound on the loop: a line
   that runs along a limit, stepping tol / 2 uncertified, for longer stops there, status 2). */
#define MAX_PROBES 1000000
/* The most bisection steps of a travel's last bracket (from at most hmax to tol: 128
   halvings cover any double bracket). */
#define MAX_REFINE 128

/* Where the legs are at a pose: R, the platform joints P_i = x + R p_i and the legs L_i = P_i - a_i
   in N, their lengths. */
typedef struct {
    double R[9], P[18], L[18], l[6];
} pose_geometry;

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void geometry(const double *p, const double q[6], pose_geometry *g)
{
    double om[3], al[3];
    int i, k;
    sw_orientation(q, SW_ZERO6, SW_ZERO6, g->R, om, al, 0);
    for (i = 0; i < 6; ++i) {
        const double *pj = p + STEWART_P_PLATFORM + 3 * i, *aj = p + STEWART_P_BASE + 3 * i;
        for (k = 0; k < 3; ++k) {
            g->P[3 * i + k] = q[k] + (g->R[3 * k] * pj[0] + g->R[3 * k + 1] * pj[1]
                                      + g->R[3 * k + 2] * pj[2]);
            g->L[3 * i + k] = g->P[3 * i + k] - aj[k];
        }
        g->l[i] = sqrt(dot3(g->L + 3 * i, g->L + 3 * i));
    }
}

/* The angle between a and b as the pair (|a x b|, a . b), each scaled by |a| |b|: its
   atan2 is the angle, accurate near 0 and pi. */
typedef struct {
    double s, c;
} angle_pair;

static angle_pair angle_of(const double a[3], const double b[3])
{
    double c0 = a[1] * b[2] - a[2] * b[1], c1 = a[2] * b[0] - a[0] * b[2];
    double c2 = a[0] * b[1] - a[1] * b[0];
    angle_pair out;
    out.s = sqrt(c0 * c0 + c1 * c1 + c2 * c2);
    out.c = dot3(a, b);
    return out;
}

/* Whether angle x is larger than angle y (both in [0, pi]: the sign of sin(x - y), as the
   positive scales of the pairs do not change it); the largest of six then takes one atan2. */
static int wider(angle_pair x, angle_pair y)
{
    return x.s * y.c - x.c * y.s > 0.0;
}

static double clamp01(double x)
{
    return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x);
}

/* The squared distance between segments p1-q1 and p2-q2 (Ericson, Real-Time Collision Detection,
   5.1.9: the closest points' parameters s, t clamped to [0, 1] in turn). */
static double segment_distance2(const double p1[3], const double q1[3], const double p2[3],
                                const double q2[3])
{
    double d1[3], d2[3], r[3], a, e, f, s, t, out = 0.0;
    int k;
    for (k = 0; k < 3; ++k) {
        d1[k] = q1[k] - p1[k];
        d2[k] = q2[k] - p2[k];
        r[k] = p1[k] - p2[k];
    }
    a = dot3(d1, d1);
    e = dot3(d2, d2);
    f = dot3(d2, r);
    if (a <= 0.0 && e <= 0.0) {
        s = t = 0.0;
    } else if (a <= 0.0) {
        s = 0.0;
        t = clamp01(f / e);
    } else {
        double c = dot3(d1, r);
        if (e <= 0.0) {
            t = 0.0;
            s = clamp01(-c / a);
        } else {
            double b = dot3(d1, d2), denom = a * e - b * b;
            s = denom > 0.0 ? clamp01((b * f - c * e) / denom) : 0.0;
            t = (b * s + f) / e;
            if (t < 0.0) {
                t = 0.0;
                s = clamp01(-c / a);
            } else if (t > 1.0) {
                t = 1.0;
                s = clamp01((b - c) / a);
            }
        }
    }
    for (k = 0; k < 3; ++k) {
        double dk = (p1[k] + d1[k] * s) - (p2[k] + d2[k] * t);
        out += dk * dk;
    }
    return out;
}

/* Signed distance of point x (in the shape's own frame) to a box of half edges h, or to a
   cylinder of radius h[0] and half length h[2] about local z (negative inside). */
static double box_distance(const double x[3], const double h[3])
{
    double d0 = fabs(x[0]) - h[0], d1 = fabs(x[1]) - h[1], d2 = fabs(x[2]) - h[2];
    double o0 = PY_MAX(d0, 0.0), o1 = PY_MAX(d1, 0.0), o2 = PY_MAX(d2, 0.0);
    double inside = PY_MIN(PY_MAX(d0, PY_MAX(d1, d2)), 0.0);
    return sqrt(o0 * o0 + o1 * o1 + o2 * o2) + inside;
}

static double cylinder_distance(const double x[3], const double h[3])
{
    double dr = sqrt(x[0] * x[0] + x[1] * x[1]) - h[0], dz = fabs(x[2]) - h[2];
    double o0 = PY_MAX(dr, 0.0), o1 = PY_MAX(dz, 0.0);
    return sqrt(o0 * o0 + o1 * o1) + PY_MIN(PY_MAX(dr, dz), 0.0);
}

static double shape_distance(int shape, const double a[3], const double d[3], double t,
                             const double h[3])
{
    double x[3];
    x[0] = a[0] + t * d[0];
    x[1] = a[1] + t * d[1];
    x[2] = a[2] + t * d[2];
    return shape == STEWART_SHAPE_BOX ? box_distance(x, h) : cylinder_distance(x, h);
}

/* The least signed distance of segment a + t d, t in [0, 1] (in the shape's frame), to a box or
   cylinder: a signed distance of a convex set is convex, and so along a segment; golden-section
   search finds its minimum. */
static double segment_shape_distance(int shape, const double a[3], const double d[3],
                                     const double h[3])
{
    const double g = 0.6180339887498949;
    double lo = 0.0, hi = 1.0, x1 = hi - g, x2 = g;
    double f1 = shape_distance(shape, a, d, x1, h), f2 = shape_distance(shape, a, d, x2, h);
    double best = PY_MIN(shape_distance(shape, a, d, 0.0, h), shape_distance(shape, a, d, 1.0, h));
    int k;
    for (k = 0; k < GOLDEN_STEPS; ++k) {
        if (f1 <= f2) {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = shape_distance(shape, a, d, x1, h);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = shape_distance(shape, a, d, x2, h);
        }
    }
    return PY_MIN(best, PY_MIN(f1, f2));
}

/* margin[k] = min(margin[k], x), where[k] the element of the least. */
static void take(double *margin, int *where, int k, double x, int element)
{
    if (x < margin[k]) {
        margin[k] = x;
        where[k] = element;
    }
}

/* Obstacle record o placed in N at the pose: its centre cw and rotation Rw (local to N). */
static void obstacle_place(const double *o, const pose_geometry *g, const double q[6],
                           double cw[3], double Rw[9])
{
    const double *c = o + 2, *Ro = o + 5;
    int j, k;
    if (o[1] == STEWART_BODY_PLATFORM) {   /* the obstacle moves with the platform */
        for (j = 0; j < 3; ++j) {
            cw[j] = q[j] + dot3(g->R + 3 * j, c);
            for (k = 0; k < 3; ++k)
                Rw[3 * j + k] = g->R[3 * j] * Ro[k] + g->R[3 * j + 1] * Ro[3 + k]
                                + g->R[3 * j + 2] * Ro[6 + k];
        }
    } else {
        for (j = 0; j < 3; ++j)
            cw[j] = c[j];
        for (j = 0; j < 9; ++j)
            Rw[j] = Ro[j];
    }
}

/* The least margin of the legs to obstacle record o (the signed distance of a leg's segment
   to the shape less the leg's radius) into m, w as obstacle ob. A leg whose distance to the
   shape's bounding sphere (a lower bound) is no less than the least margin so far cannot give
   a lesser one and is skipped: the box and cylinder searches run for the near legs only. With
   sign_only, a leg clear of the sphere gives that bound (a positive lower bound of its margin,
   never above it). */
static void obstacle_margins(const double *o, int ob, const pose_geometry *g, const double q[6],
                             const double *base, double radius, int sign_only, double *m, int *w)
{
    const double *h = o + 14;
    const int shape = (int)o[0];
    double cw[3], Rw[9], a[18], d[18], bound[6];
    const double zero[3] = {0.0, 0.0, 0.0};
    const double outer = shape == STEWART_SHAPE_SPHERE ? h[0]
                       : sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    int i, j, k, done[6] = {0, 0, 0, 0, 0, 0};
    obstacle_place(o, g, q, cw, Rw);
    for (i = 0; i < 6; ++i) {   /* the leg's ends in the obstacle's frame: Rw^T (x - cw) */
        double ea[3], eb[3], b[3];
        for (j = 0; j < 3; ++j) {
            ea[j] = base[3 * i + j] - cw[j];
            eb[j] = g->P[3 * i + j] - cw[j];
        }
        for (k = 0; k < 3; ++k) {
            a[3 * i + k] = Rw[k] * ea[0] + Rw[3 + k] * ea[1] + Rw[6 + k] * ea[2];
            b[k] = Rw[k] * eb[0] + Rw[3 + k] * eb[1] + Rw[6 + k] * eb[2];
            d[3 * i + k] = b[k] - a[3 * i + k];
        }
        bound[i] = sqrt(segment_distance2(a + 3 * i, b, zero, zero)) - outer - radius;
    }
    for (k = 0; k < 6; ++k) {   /* legs by their bound, nearest first */
        int next = -1;
        for (i = 0; i < 6; ++i)
            if (!done[i] && (next < 0 || bound[i] < bound[next]))
                next = i;
        done[next] = 1;
        if (shape == STEWART_SHAPE_SPHERE || (sign_only && bound[next] >= 0.0)) {
            /* the sphere's exact; the bound of a leg surely clear (sign-only), a lower bound
               of its margin that travel's steps may rest on */
            take(m, w, STEWART_LIMIT_OBSTACLE, bound[next], 6 * ob + next);
        } else if (bound[next] < m[STEWART_LIMIT_OBSTACLE]) {
            take(m, w, STEWART_LIMIT_OBSTACLE,
                 segment_shape_distance(shape, a + 3 * next, d + 3 * next, h) - radius,
                 6 * ob + next);
        }
    }
}

void stewart_reach_present(const double *params, const double *reach, int has_qd, int has_qdd,
                           int *present)
{
    int drive = has_qd && has_qdd;
    present[STEWART_LIMIT_STROKE_MIN] = params[STEWART_P_LEG_MIN] > 0.0;
    present[STEWART_LIMIT_STROKE_MAX] = isfinite(params[STEWART_P_LEG_MAX]) != 0;
    present[STEWART_LIMIT_BASE_CONE] = RP(HAS_JOINTS) != 0.0;
    present[STEWART_LIMIT_PLATFORM_CONE] = RP(HAS_JOINTS) != 0.0;
    present[STEWART_LIMIT_LEG_CLEARANCE] = RP(HAS_CLEARANCE) != 0.0;
    present[STEWART_LIMIT_OBSTACLE] = RP(HAS_CLEARANCE) != 0.0 && RP(N_OBSTACLES) > 0.0;
    present[STEWART_LIMIT_COND] = isfinite(RP(COND_LIMIT)) != 0;
    present[STEWART_LIMIT_SPEED] = has_qd && isfinite(RP(SPEED));
    present[STEWART_LIMIT_ACCELERATION] = drive && isfinite(RP(ACCELERATION));
    present[STEWART_LIMIT_FORCE] = drive && isfinite(RP(FORCE));
}

/* Bounds of J's extreme singular values: *upper = ||J||_F >= s_max, *lower = 1 / ||J^-1||_F
   <= s_min (LU of J and six solves, ~0.2 us against sw_singular_range's ~0.8 us); 0 when the
   LU finds J singular. */
static int sigma_bounds(const double J[36], double *upper, double *lower)
{
    double LU[36], fj = 0.0, fi = 0.0;
    int order[12], k, c;
    for (k = 0; k < 36; ++k) {
        LU[k] = J[k];
        fj += J[k] * J[k];
    }
    for (k = 0; k < 6; ++k) {
        order[k] = k;
        order[6 + k] = k;
    }
    if (!(sw_lu_factor(LU, order) > 0.0))
        return 0;
    for (c = 0; c < 6; ++c) {   /* column c of J^-1: J x = e_c */
        double b[6];
        for (k = 0; k < 6; ++k)
            b[k] = order[k] == c ? 1.0 : 0.0;
        sw_lu_solve(LU, b);
        for (k = 0; k < 6; ++k)
            fi += b[k] * b[k];
    }
    *upper = sqrt(fj);
    *lower = 1.0 / sqrt(fi);
    return 1;
}

/* Whether cond(J) is surely below limit: ||J||_F ||J^-1||_F bounds cond_2(J) from above, with
   a relative allowance of 1e-9 for the rounding of the bound. A sign-only evaluation (travel)
   takes the SVD only when this fails. */
static int cond_surely_below(const double J[36], double limit)
{
    double upper, lower;
    return sigma_bounds(J, &upper, &lower) && upper * (1.0 + 1e-9) < limit * lower;
}

/* The scaled leg Jacobian at the geometry g (kinematics.c's rows [u_i, (R p_i) x u_i /
   char_length]); 0 when an entry is not finite. */
static int leg_jacobian(const double *p, const double q[6], const pose_geometry *g, double J[36])
{
    double U[18], R[18];
    int i, k;
    for (i = 0; i < 6; ++i)
        for (k = 0; k < 3; ++k) {
            U[3 * i + k] = g->L[3 * i + k] / g->l[i];
            R[3 * i + k] = g->P[3 * i + k] - q[k];
        }
    sw_jacobian_rows(U, R, 1.0 / p[STEWART_P_CHAR_LENGTH], J);
    for (i = 0; i < 36; ++i)
        if (!isfinite(J[i]))
            return 0;
    return 1;
}

/* cond(J) of the scaled leg Jacobian at the geometry g (leg_jacobian, by the core's one
   sw_condition, linalg.c); with sign_only, 0 when cond_surely_below the limit (the value is
   then not needed). */
static double condition(const double *p, const double q[6], const pose_geometry *g,
                        double limit, int sign_only)
{
    double J[36];
    if (!leg_jacobian(p, q, g, J))
        return HUGE_VAL;
    if (sign_only && cond_surely_below(J, limit))
        return 0.0;
    return sw_condition(J);
}

/* Both joint cones' margins: the cone less the widest angle of the six legs to the joint's
   axis (the base joint's fixed in N, the platform joint's turning with R). */
static void cone_margins(const double *reach, const pose_geometry *g, double *m, int *w)
{
    angle_pair base_wide = {0.0, 1.0}, top_wide = {0.0, 1.0};
    int i, j, base_at = 0, top_at = 0;
    for (i = 0; i < 6; ++i) {
        const double *c = reach + STEWART_R_PLATFORM_AXES + 3 * i;
        double Rc[3];
        angle_pair b, t;
        for (j = 0; j < 3; ++j)   /* the platform joint's axis in N */
            Rc[j] = dot3(g->R + 3 * j, c);
        b = angle_of(g->L + 3 * i, reach + STEWART_R_BASE_AXES + 3 * i);
        t = angle_of(g->L + 3 * i, Rc);
        if (i == 0 || wider(b, base_wide)) {
            base_wide = b;
            base_at = i;
        }
        if (i == 0 || wider(t, top_wide)) {
            top_wide = t;
            top_at = i;
        }
    }
    take(m, w, STEWART_LIMIT_BASE_CONE, RP(BASE_CONE) - atan2(base_wide.s, base_wide.c), base_at);
    take(m, w, STEWART_LIMIT_PLATFORM_CONE, RP(PLATFORM_CONE) - atan2(top_wide.s, top_wide.c),
         top_at);
}

/* The geometric limits' and cond(J)'s margins; with sign_only, a margin that is surely
   positive may be left larger than it is (cond(J): the limit itself) or smaller (obstacles:
   a positive lower bound). */
static void geometric_margins(const double *p, const double *reach, const double q[6],
                              const int present[], int sign_only, double *m, int *w)
{
    const double *base = p + STEWART_P_BASE;
    pose_geometry g;
    int i, j, pair;
    geometry(p, q, &g);
    if (present[STEWART_LIMIT_COND])
        m[STEWART_LIMIT_COND] = RP(COND_LIMIT) - condition(p, q, &g, RP(COND_LIMIT), sign_only);
    for (i = 0; i < 6; ++i) {
        if (present[STEWART_LIMIT_STROKE_MIN])
            take(m, w, STEWART_LIMIT_STROKE_MIN, g.l[i] - p[STEWART_P_LEG_MIN], i);
        if (present[STEWART_LIMIT_STROKE_MAX])
            take(m, w, STEWART_LIMIT_STROKE_MAX, p[STEWART_P_LEG_MAX] - g.l[i], i);
    }
    if (present[STEWART_LIMIT_BASE_CONE])
        cone_margins(reach, &g, m, w);
    if (present[STEWART_LIMIT_LEG_CLEARANCE]) {
        double d2, least = HUGE_VAL;
        int at = 0;
        for (i = 0, pair = 0; i < 6; ++i)   /* the nearest pair, then one square root */
            for (j = i + 1; j < 6; ++j, ++pair) {
                d2 = segment_distance2(base + 3 * i, g.P + 3 * i, base + 3 * j, g.P + 3 * j);
                if (d2 < least) {
                    least = d2;
                    at = pair;
                }
            }
        take(m, w, STEWART_LIMIT_LEG_CLEARANCE, sqrt(least) - 2.0 * RP(LEG_RADIUS), at);
    }
    if (present[STEWART_LIMIT_OBSTACLE]) {
        int o, n = (int)RP(N_OBSTACLES);
        for (o = 0; o < n && o < STEWART_MAX_OBSTACLES; ++o)
            obstacle_margins(reach + STEWART_R_OBSTACLES + STEWART_OBSTACLE_SIZE * o, o, &g, q,
                             base, RP(LEG_RADIUS), sign_only, m, w);
    }
}

/* Leg speed, acceleration and rack force against the drives' bounds. */
static void drive_margins(const double *p, const double *reach, const double q[6],
                          const double qd[6], const double qdd[6], const int present[], double *m,
                          int *w)
{
    sw_ws ws;
    int i;
    sw_ws_init(&ws);
    sw_orientation(q, qd, qdd, ws.R, ws.om, ws.al, 0);
    sw_twist_forces(p, q, qd, qdd, ws.al, &ws);
    for (i = 0; i < 6; ++i) {
        if (present[STEWART_LIMIT_SPEED])
            take(m, w, STEWART_LIMIT_SPEED, RP(SPEED) - fabs(ws.leg[3 * i + 1]), i);
        if (present[STEWART_LIMIT_ACCELERATION])
            take(m, w, STEWART_LIMIT_ACCELERATION, RP(ACCELERATION) - fabs(ws.leg[3 * i + 2]), i);
    }
    if (present[STEWART_LIMIT_FORCE]) {
        double free[STEWART_N_PARAMS], sigma[6];
        int k;
        for (k = 0; k < STEWART_N_PARAMS; ++k)   /* the stroke is a limit here, not a refusal */
            free[k] = p[k];
        free[STEWART_P_LEG_MIN] = 0.0;
        free[STEWART_P_LEG_MAX] = HUGE_VAL;
        if (stewart_inverse_dynamics(free, q, qd, qdd, sigma) != STEWART_OK)
            take(m, w, STEWART_LIMIT_FORCE, -HUGE_VAL, 0);
        else
            for (i = 0; i < 6; ++i)
                take(m, w, STEWART_LIMIT_FORCE, RP(FORCE) - fabs(sigma[i]), i);
    }
}

static int finite6(const double *x)
{
    int k;
    if (!x)
        return 1;
    for (k = 0; k < 6; ++k)
        if (!isfinite(x[k]))
            return 0;
    return 1;
}

/* The margins of the present limits; returns the binding limit (-1: inside every one). */
static int margins_of(const double *params, const double *reach, const int present[],
                      int sign_only, const double q[6], const double *qd, const double *qdd,
                      double *m, int *w)
{
    int k;
    for (k = 0; k < STEWART_N_LIMITS; ++k) {
        m[k] = HUGE_VAL;
        w[k] = 0;
    }
    geometric_margins(params, reach, q, present, sign_only, m, w);
    if (qd && (present[STEWART_LIMIT_SPEED] || present[STEWART_LIMIT_ACCELERATION] ||
               present[STEWART_LIMIT_FORCE]))
        drive_margins(params, reach, q, qd, qdd ? qdd : SW_ZERO6, present, m, w);
    for (k = 0; k < STEWART_N_LIMITS; ++k)
        if (m[k] < 0.0)
            return k;
    return -1;
}

int stewart_reach_margins(const double *params, const double *reach, const double q[6],
                          const double *qd, const double *qdd, double margin[STEWART_N_LIMITS],
                          int *where)
{
    int present[STEWART_N_LIMITS], k;
    if (!finite6(q) || !finite6(qd) || !finite6(qdd)) {
        for (k = 0; k < STEWART_N_LIMITS; ++k) {
            margin[k] = NAN;
            where[k] = 0;
        }
        return STEWART_N_LIMITS;
    }
    stewart_reach_present(params, reach, qd != 0, qdd != 0, present);
    return margins_of(params, reach, present, 0, q, qd, qdd, margin, where);
}

long stewart_reach_batch(const double *params, const double *reach, long n, const double *Q,
                         const double *QD, const double *QDD, double *margins, int *where,
                         int *binding)
{
    int present[STEWART_N_LIMITS];
    long k, inside = 0;
    stewart_reach_present(params, reach, QD != 0, QDD != 0, present);
    for (k = 0; k < n; ++k) {
        const double *q = Q + 6 * k, *qd = QD ? QD + 6 * k : 0, *qdd = QDD ? QDD + 6 * k : 0;
        if (!finite6(q) || !finite6(qd) || !finite6(qdd))
            return -(1 + k);
        binding[k] = margins_of(params, reach, present, 0, q, qd, qdd,
                                margins + STEWART_N_LIMITS * k, where + STEWART_N_LIMITS * k);
        inside += binding[k] < 0;
    }
    return inside;
}

long stewart_reach_binding(const double *params, const double *reach, long n, const double *Q,
                           int *binding)
{
    int present[STEWART_N_LIMITS], w[STEWART_N_LIMITS];
    double m[STEWART_N_LIMITS];
    long k, inside = 0;
    stewart_reach_present(params, reach, 0, 0, present);
    for (k = 0; k < n; ++k) {
        if (!finite6(Q + 6 * k))
            return -(1 + k);
        binding[k] = margins_of(params, reach, present, 1, Q + 6 * k, 0, 0, m, w);
        inside += binding[k] < 0;
    }
    return inside;
}

/* A line of poses f = q0 + t dir in a frame (frame: mov, fix of frames.c; NULL: C itself), and
   what bounds how fast its limits' margins can fall along it (travel_rates):

   the frame's origin moves at |v| = |dir[0..2]| (its positions are turned by R_fix alone); the
   angles are z-y-x (R = Rz Ry Rx, rotations.c), so the angular velocity of R (the frame's
   turned by R_fix and R_mov, a rotation's speed unchanged) is e_x' thx' + e_y' thy' + e_z thz'
   with e_x' . e_z = -sin(thy), the others orthogonal: |w|^2 <= |th'|^2 + 2 |thx' thz'| = om^2
   at every t. A point z of the platform (in C) is at x + R z = R_fix f + fix - R mov + R z,
   so it moves at no more than speed_i = |v| + om |z - mov| (platform joint i: z = p_i). */
typedef struct {
    const double *params, *reach, *q0, *dir, *frame;
    double Rt[9], Rw[9];
    int present[STEWART_N_LIMITS];   /* cond(J) left out: travel_cond takes it */
    int cond, moving_obstacles;
    double lin, om, hmax, speed[6], vmax, arm[6], rho[6];   /* |p_i|, |p_i - mov| */
} travel_line;

static void travel_rates(travel_line *line)
{
    const double *d = line->dir, *p = line->params;
    double mov[3] = {0.0, 0.0, 0.0};
    int i, k, n = (int)line->reach[STEWART_R_N_OBSTACLES];
    line->lin = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    line->om = sqrt(d[3] * d[3] + d[4] * d[4] + d[5] * d[5] + 2.0 * fabs(d[3] * d[5]));
    if (line->frame)
        for (k = 0; k < 3; ++k)
            mov[k] = line->frame[k];
    line->vmax = 0.0;
    for (i = 0; i < 6; ++i) {
        const double *z = p + STEWART_P_PLATFORM + 3 * i;
        double r[3] = {z[0] - mov[0], z[1] - mov[1], z[2] - mov[2]};
        line->rho[i] = sqrt(dot3(r, r));
        line->speed[i] = line->lin + line->om * line->rho[i];
        line->arm[i] = sqrt(dot3(z, z));
        line->vmax = PY_MAX(line->vmax, line->speed[i]);
    }
    line->cond = line->present[STEWART_LIMIT_COND];
    line->present[STEWART_LIMIT_COND] = 0;
    line->moving_obstacles = 0;
    if (line->present[STEWART_LIMIT_OBSTACLE])
        for (k = 0; k < n && k < STEWART_MAX_OBSTACLES; ++k)
            if (line->reach[STEWART_R_OBSTACLES + STEWART_OBSTACLE_SIZE * k + 1]
                == STEWART_BODY_PLATFORM)
                line->moving_obstacles = 1;
}

/* x / rate, +inf where the rate is 0 (the margin cannot fall) or x is (a limit not present). */
static double safe_step(double x, double rate)
{
    return rate > 0.0 ? x / rate : HUGE_VAL;
}

/* How fast the obstacle margins can fall for a step of at most hmax from the pose (q, R): a
   leg's segment runs from a_i (fixed in N) to P_i (in C). To an obstacle fixed in N its points
   move at no more than max speed_i; to one on the platform P_i is still and a_i moves, seen
   from C, as the platform's point at a_i: |v| + om |a_i - o| with o = x + R mov the frame's
   origin, which moves at |v| (the distance grows by at most |v| hmax). The signed distance to
   a convex shape (and to a sphere about it, the sign-only bound) is 1-Lipschitz. */
static double obstacle_rate(const travel_line *line, const double q[6], const pose_geometry *g)
{
    const double *base = line->params + STEWART_P_BASE;
    double o[3], far = 0.0;
    int i, k;
    if (!line->moving_obstacles)
        return line->vmax;
    for (k = 0; k < 3; ++k)
        o[k] = q[k] + (line->frame ? dot3(g->R + 3 * k, line->frame) : 0.0);
    for (i = 0; i < 6; ++i) {
        double r[3] = {base[3 * i] - o[0], base[3 * i + 1] - o[1], base[3 * i + 2] - o[2]};
        far = PY_MAX(far, sqrt(dot3(r, r)));
    }
    return PY_MAX(line->vmax, line->lin + line->om * (far + line->lin * line->hmax));
}

/* The step of travel_cond for s_max, s_min: E / D, or with Taylor's bound (grow >= 0) the
   larger of that and the root of G h + M h^2 / 2 = E. */
static double travel_cond_step(double c, double smax, double smin, double rate, double grow,
                               double bend)
{
    const double e = (c * smin - smax) / (1.0 + c);
    double h = safe_step(e, rate);
    if (grow >= 0.0)
        h = PY_MAX(h, 2.0 * e / (grow + sqrt(grow * grow + 2.0 * bend * e)));
    return h;
}

/* ||J'||_F at the pose, exactly: the platform's velocity along the line (v = R_fix dir[0..2],
   w = R_fix E(th) dir[3..5], E's columns Rz Ry e_x, Rz e_y, e_z) moves P_i at v + w x (P_i - o),
   o = x + R mov the frame's origin; row i's derivatives are u_i' = (P_i')_perp / l_i and
   ((w x r_i) x u_i + r_i x u_i') / lc, r_i = P_i - x. */
static double jacobian_rate(const travel_line *line, const double f[6], const double q[6],
                            const pose_geometry *g)
{
    const double *d = line->dir, lc = line->params[STEWART_P_CHAR_LENGTH];
    const double cy = cos(f[4]), sy = sin(f[4]), cz = cos(f[5]), sz = sin(f[5]);
    const double wf[3] = {cy * cz * d[3] - sz * d[4], cy * sz * d[3] + cz * d[4], -sy * d[3] + d[5]};
    double w[3], v[3], o[3], sum = 0.0;
    int i, k;
    for (k = 0; k < 3; ++k) {
        w[k] = line->frame ? dot3(line->Rw + 3 * k, wf) : wf[k];
        v[k] = line->frame ? dot3(line->Rw + 3 * k, d) : d[k];
        o[k] = q[k] + (line->frame ? dot3(g->R + 3 * k, line->frame) : 0.0);
    }
    for (i = 0; i < 6; ++i) {
        const double *P = g->P + 3 * i, *L = g->L + 3 * i;
        double e[3], r[3], u[3], pd[3], ud[3], wr[3], x[3], along;
        for (k = 0; k < 3; ++k) {
            e[k] = P[k] - o[k];
            r[k] = P[k] - q[k];
            u[k] = L[k] / g->l[i];
        }
        pd[0] = v[0] + w[1] * e[2] - w[2] * e[1];
        pd[1] = v[1] + w[2] * e[0] - w[0] * e[2];
        pd[2] = v[2] + w[0] * e[1] - w[1] * e[0];
        along = dot3(u, pd);
        for (k = 0; k < 3; ++k)
            ud[k] = (pd[k] - along * u[k]) / g->l[i];
        wr[0] = w[1] * r[2] - w[2] * r[1];
        wr[1] = w[2] * r[0] - w[0] * r[2];
        wr[2] = w[0] * r[1] - w[1] * r[0];
        x[0] = (wr[1] * u[2] - wr[2] * u[1]) + (r[1] * ud[2] - r[2] * ud[1]);
        x[1] = (wr[2] * u[0] - wr[0] * u[2]) + (r[2] * ud[0] - r[0] * ud[2]);
        x[2] = (wr[0] * u[1] - wr[1] * u[0]) + (r[0] * ud[1] - r[1] * ud[0]);
        sum += dot3(ud, ud) + dot3(x, x) / (lc * lc);
    }
    return sqrt(sum);
}

/* A bound of ||J''||_F along a step (legs no shorter than l_lo): with |P_i'| <= speed_i and
   |P_i''| <= a_i = (|w'| + om^2) |p_i - mov|, |w'| <= |thx'| (|thy'| + |thz'|) + |thy'| |thz'|
   (E's columns turn at |thy'| + |thz'|, |thz'|, 0), |u_i'| <= speed_i / l_lo and
   |u_i''| <= (2 a_i + 3 speed_i^2 / l_lo) / l_lo (from L'' = l u'' + 2 l' u' + l'' u), and
   (r x u)'' = r'' x u + 2 r' x u' + r x u'' with |r'| <= om |p_i|, |r''| <= (|w'| + om^2) |p_i|. */
static double jacobian_curvature(const travel_line *line, double l_lo)
{
    const double *d = line->dir, lc = line->params[STEWART_P_CHAR_LENGTH];
    const double turn = fabs(d[3]) * (fabs(d[4]) + fabs(d[5])) + fabs(d[4]) * fabs(d[5]);
    const double spin = turn + line->om * line->om;
    double sum = 0.0;
    int i;
    for (i = 0; i < 6; ++i) {
        const double s = line->speed[i], a = spin * line->rho[i];
        const double udd = (2.0 * a + 3.0 * s * s / l_lo) / l_lo;
        const double rdd = line->arm[i] * (spin + 2.0 * line->om * s / l_lo + udd) / lc;
        sum += udd * udd + rdd * rdd;
    }
    return sqrt(sum);
}

/* cond(J)'s margin at the pose, and in *step how far along the line it surely holds (0 when
   it does not): by Weyl's inequality each singular value moves by no more than
   e(h) = ||J(t + h) - J(t)||_2 <= ||J(t + h) - J(t)||_F, and cond(J) = s_max / s_min stays
   below c while s_max + e <= c (s_min - e), e <= E = (c s_min - s_max) / (1 + c). Two bounds
   of e, the larger step taken: e <= D h, D a bound of ||J'||_F over the step (row i moves at
   no more than |u_i'| <= speed_i / l_lo and |(R p_i x u_i)'| / lc <= arm_i (om + speed_i /
   l_lo) / lc); and Taylor's e <= G h + M h^2 / 2, G = ||J'||_F at t (jacobian_rate), M
   (jacobian_curvature), which near a limit is G's alone. s_max and s_min from sigma_bounds
   where that bound already allows `enough`, else from sw_singular_range; Taylor's bound only
   where D's does not allow `enough`. */
static double travel_cond(const travel_line *line, const double f[6], const double q[6],
                          const pose_geometry *g, double l_lo, double enough, double *step)
{
    const double c = line->reach[STEWART_R_COND_LIMIT], lc = line->params[STEWART_P_CHAR_LENGTH];
    double J[36], smax, smin, d2 = 0.0, rate, grow = -1.0, bend = 0.0;
    int i, bounded;
    *step = 0.0;
    if (!leg_jacobian(line->params, q, g, J))
        return -HUGE_VAL;
    for (i = 0; i < 6; ++i) {
        double du = line->speed[i] / l_lo, dr = line->arm[i] * (line->om + du) / lc;
        d2 += du * du + dr * dr;
    }
    rate = sqrt(d2);
    bounded = sigma_bounds(J, &smax, &smin) && smax * (1.0 + 1e-9) < c * smin;
    if (!(bounded && travel_cond_step(c, smax, smin, rate, grow, bend) >= enough)) {
        grow = jacobian_rate(line, f, q, g);
        bend = jacobian_curvature(line, l_lo);
    }
    if (!(bounded && travel_cond_step(c, smax, smin, rate, grow, bend) >= enough)) {
        sw_singular_range(J, &smax, &smin);
        if (!(smin > 0.0 && smax / smin <= c))
            return smin > 0.0 ? c - smax / smin : -HUGE_VAL;
    }
    *step = travel_cond_step(c, smax, smin, rate, grow, bend);
    return c - smax / smin;
}

/* The pose at t on the line: its binding limit (-1: inside every one) and where (*w). Each
   limit k is surely held on [.., horizon[k]]; the limits whose horizon ends no more than
   `ahead` past t (the last step: those that would hold the next one) are evaluated here and,
   inside, their horizon moved to t + h_k, h_k the margin over its bound of how fast it can
   fall (travel_rates, obstacle_rate, travel_cond), at most cap = min(hmax, l_min / (2 vmax)),
   which keeps every leg longer than l_lo = l_min - vmax cap (l_min the shortest at t) on
   [t, t + cap]: the rates divide by that. The others are surely held at t and not evaluated. */
static int travel_probe(const travel_line *line, double t, double ahead, double horizon[],
                        int *w)
{
    double f[6], q[6], m[STEWART_N_LIMITS], rate[STEWART_N_LIMITS], l_lo, cap, others = HUGE_VAL;
    int ws[STEWART_N_LIMITS], due[STEWART_N_LIMITS], k, b;
    pose_geometry g;
    for (k = 0; k < 6; ++k)
        f[k] = line->q0[k] + t * line->dir[k];
    if (line->frame)
        sw_frame_to_platform(line->frame, line->frame + 6, line->Rt, line->Rw, f, q);
    else
        for (k = 0; k < 6; ++k)
            q[k] = f[k];
    for (k = 0; k < STEWART_N_LIMITS; ++k)
        due[k] = line->present[k] && horizon[k] - t <= ahead;
    due[STEWART_LIMIT_BASE_CONE] = due[STEWART_LIMIT_PLATFORM_CONE] =   /* one call takes both */
        due[STEWART_LIMIT_BASE_CONE] || due[STEWART_LIMIT_PLATFORM_CONE];
    b = margins_of(line->params, line->reach, due, 1, q, 0, 0, m, ws);
    geometry(line->params, q, &g);
    l_lo = g.l[0];
    for (k = 1; k < 6; ++k)
        l_lo = PY_MIN(l_lo, g.l[k]);
    cap = PY_MIN(line->hmax, safe_step(0.5 * l_lo, line->vmax));
    l_lo -= line->vmax * cap;
    rate[STEWART_LIMIT_STROKE_MIN] = rate[STEWART_LIMIT_STROKE_MAX] = line->vmax;
    rate[STEWART_LIMIT_BASE_CONE] = line->vmax / l_lo;   /* |u_i'| <= speed_i / l_i */
    rate[STEWART_LIMIT_PLATFORM_CONE] = line->vmax / l_lo + line->om;   /* and R c_i turns */
    rate[STEWART_LIMIT_LEG_CLEARANCE] = 2.0 * line->vmax;   /* both segments move */
    rate[STEWART_LIMIT_OBSTACLE] = due[STEWART_LIMIT_OBSTACLE] ? obstacle_rate(line, q, &g) : 0.0;
    for (k = 0; k < STEWART_LIMIT_COND; ++k)
        if (b < 0 && due[k])
            horizon[k] = PY_MAX(horizon[k], t + PY_MIN(cap, safe_step(m[k], rate[k])));
    for (k = 0; k < STEWART_LIMIT_COND; ++k)
        others = PY_MIN(others, horizon[k]);
    if (b < 0 && line->cond && horizon[STEWART_LIMIT_COND] - t <= ahead) {
        double hc;
        if (travel_cond(line, f, q, &g, l_lo, PY_MIN(cap, others - t), &hc) < 0.0) {
            b = STEWART_LIMIT_COND;
            ws[b] = 0;
        } else {
            horizon[STEWART_LIMIT_COND] = PY_MAX(horizon[STEWART_LIMIT_COND],
                                                 t + PY_MIN(cap, hc));
        }
    }
    *w = b >= 0 ? ws[b] : -1;
    return b;
}

/* The least horizon (where conservative advancement has got to) and in *near its limit. */
static double frontier(const double horizon[], int *near)
{
    double out = HUGE_VAL;
    int k;
    *near = -1;
    for (k = 0; k < STEWART_N_LIMITS; ++k)
        if (horizon[k] < out) {
            out = horizon[k];
            *near = k;
        }
    return out;
}

int stewart_reach_travel(const double *params, const double *reach, const double *frame,
                         const double q0[6], const double dir[6], double hmax, double smax,
                         double tol, double *s, int *limit, int *where)
{
    travel_line line;
    int b, w, near, probes, k;
    double lo = 0.0, hi, reach_to, horizon[STEWART_N_LIMITS];
    *s = 0.0;
    *limit = *where = -1;
    if (!finite6(q0) || !finite6(dir) || (frame && (!finite6(frame) || !finite6(frame + 6))) ||
        !(tol > 0.0) || !(hmax > 0.0) || !(smax > 0.0) || !isfinite(smax) ||
        !(smax / hmax <= MAX_MARCH / 64.0))
        return -1;
    line.params = params;
    line.reach = reach;
    line.q0 = q0;
    line.dir = dir;
    line.frame = frame;
    line.hmax = hmax;
    if (frame)
        sw_frame_rotations(frame, frame + 6, line.Rt, line.Rw);
    stewart_reach_present(params, reach, 0, 0, line.present);
    travel_rates(&line);
    for (k = 0; k < STEWART_N_LIMITS; ++k)
        horizon[k] = line.present[k] || (k == STEWART_LIMIT_COND && line.cond) ? 0.0 : HUGE_VAL;
    b = travel_probe(&line, 0.0, 0.0, horizon, &w);
    if (b >= 0) {
        *limit = b;
        *where = w;
        return 1;
    }
    /* Conservative advancement: [0, frontier] is inside every limit; the next pose is there,
       or tol / 2 past lo where the frontier is nearer (a limit within its rate x tol / 2). */
    for (probes = 0;; ++probes) {
        reach_to = frontier(horizon, &near);
        if (reach_to >= smax) {
            *s = smax;
            return 0;
        }
        if (probes >= MAX_PROBES) {   /* a line grazing a limit for MAX_PROBES x tol / 2 */
            *s = lo;
            *limit = near;
            *where = 0;
            return 2;
        }
        hi = PY_MIN(PY_MAX(reach_to, lo + 0.5 * tol), smax);
        b = travel_probe(&line, hi, hi - lo, horizon, &w);
        if (b >= 0)
            break;
        lo = hi;
    }
    /* lo inside, hi outside, everything between surely inside or no wider than tol / 2: what
       is left wider than tol is a pose outside at a certified step's very end (rounding),
       bisected. */
    for (probes = 0; hi - lo > tol && probes < MAX_REFINE; ++probes) {
        double mid = lo + 0.5 * (hi - lo);
        int bm, wm;
        bm = travel_probe(&line, mid, 0.0, horizon, &wm);
        if (bm >= 0) {
            hi = mid;
            b = bm;
            w = wm;
        } else {
            lo = mid;
        }
    }
    *s = lo;
    *limit = b;
    *where = w;
    return 0;
}

void stewart_leg_axes(const double *params, const double q[6], double base[18], double platform[18])
{
    pose_geometry g;
    int i, k;
    geometry(params, q, &g);
    for (i = 0; i < 6; ++i) {
        const double *L = g.L + 3 * i;
        for (k = 0; k < 3; ++k) {
            base[3 * i + k] = L[k] / g.l[i];
            /* R^T u_i: column k of R */
            platform[3 * i + k] = (g.R[k] * L[0] + g.R[3 + k] * L[1] + g.R[6 + k] * L[2]) / g.l[i];
        }
    }
}
