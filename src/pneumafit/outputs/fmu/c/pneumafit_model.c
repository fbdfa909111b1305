/* The pneumafit actuator model in C (see pneumafit_model.h).
 *
 * Every function mirrors one of pneumafit.models.kernel or pneumafit.physics
 * (named in its comment) operation for operation, so that the FMU follows the
 * compiled simulator to rounding: docs/physics.md gives the equations.
 */
#include <math.h>
#include <string.h>

#include "pneumafit_model.h"
#include "pneumafit_parts.h"

/* LuGre and a smooth friction law from outside the package: no stuck mode, no
   events (an outside law with FrictionLaw.stuck has the switch model's modes) */
#define PF_SMOOTH(m) ((m)->lugre || (PF_PART_FRICTION && !PF_PART_FRICTION_STUCK))

/* ------------------------------------------------------------------ air */

static double viscosity(double t) /* physics.air.viscosity (Sutherland) */
{
    double tr = t / PF_MU_T;
    return PF_MU_REF * tr * sqrt(tr) * (PF_MU_T + PF_MU_S) / (t + PF_MU_S);
}

static double conductivity(double t) /* physics.air.conductivity (Sutherland) */
{
    double tr = t / PF_K_T;
    return PF_K_REF * tr * sqrt(tr) * (PF_K_T + PF_K_S) / (t + PF_K_S);
}

/* --------------------------------------------------------------- checks */

int pf_check_parameters(const double *p) /* kernel.check_parameters */
{
    int i;
    for (i = 0; i < PF_NP; i++) {
        if (!isfinite(p[i])) return 0;
    }
    if (p[PF_P_bore] <= 0.0 || p[PF_P_rod] < 0.0 || p[PF_P_rod] >= p[PF_P_bore]) return 0;
    if (p[PF_P_stroke] <= 0.0 || p[PF_P_dead_volume_P] <= 0.0 || p[PF_P_dead_volume_N] <= 0.0 ||
        p[PF_P_moving_mass] <= 0.0)
        return 0;
    if (p[PF_P_supply_pressure] <= 0.0 || p[PF_P_exhaust_pressure] <= 0.0 ||
        p[PF_P_ambient_temperature] <= 0.0 || p[PF_P_wall_temperature] <= 0.0)
        return 0;
    if (p[PF_P_valve_C_supply] < 0.0 || p[PF_P_valve_C_exhaust] < 0.0 ||
        p[PF_P_valve_C_leak] < 0.0 || p[PF_P_valve_leak_width] <= 0.0)
        return 0;
    if (p[PF_P_valve_n_supply] < 1.0 / 3.0 || p[PF_P_valve_n_exhaust] < 1.0 / 3.0) return 0;
    if (p[PF_P_valve_knee_supply] < 1.0 || p[PF_P_valve_knee_exhaust] < 1.0) return 0;
    if (p[PF_P_valve_full_supply] > 1.0 || p[PF_P_valve_full_exhaust] > 1.0 ||
        p[PF_P_valve_full_supply] * p[PF_P_valve_u_sat] <= p[PF_P_valve_overlap] ||
        p[PF_P_valve_full_exhaust] * p[PF_P_valve_u_sat] <= p[PF_P_valve_overlap])
        return 0;
    if (p[PF_P_valve_b_supply] < 0.0 || p[PF_P_valve_b_exhaust] < 0.0 ||
        p[PF_P_valve_b_supply] >= p[PF_P_valve_x_laminar] ||
        p[PF_P_valve_b_exhaust] >= p[PF_P_valve_x_laminar])
        return 0;
    if (p[PF_P_valve_x_laminar] >= 1.0 || p[PF_P_valve_m] <= 0.0 ||
        p[PF_P_valve_u_sat] <= p[PF_P_valve_overlap] || p[PF_P_valve_overlap] < 0.0)
        return 0;
    if (p[PF_P_k] < 1.0 || p[PF_P_lambda] < 0.0 || p[PF_P_xi] < 0.0 || p[PF_P_beta] <= 0.0)
        return 0;
    if (p[PF_P_friction_static] < p[PF_P_friction_coulomb] || p[PF_P_friction_coulomb] < 0.0 ||
        p[PF_P_friction_viscous] < 0.0 || p[PF_P_stribeck_velocity] <= 0.0)
        return 0;
    if (p[PF_P_characteristic_length] <= 0.0 || p[PF_P_chamber_leak_conductance] < 0.0 ||
        p[PF_P_external_leak_conductance] < 0.0 || p[PF_P_valve_time_constant] < 0.0)
        return 0;
    if (!(p[PF_P_external_leak_split] >= -1.0) || !(p[PF_P_external_leak_split] <= 1.0)) return 0;
    if (!(p[PF_P_heat_area_ends] >= 0.0)) return 0;
    if (p[PF_P_wall_heat_capacity] <= 0.0) return 0;
    if (p[PF_P_stop_stiffness] < 0.0 || p[PF_P_stop_damping] < 0.0) return 0;
    if (p[PF_P_friction_stiffness] <= 0.0 || p[PF_P_friction_damping] < 0.0) return 0;
    if (p[PF_P_seal_friction_coefficient] < 0.0 || !(p[PF_P_friction_asymmetry] > -1.0) ||
        !(p[PF_P_friction_asymmetry] < 1.0))
        return 0;
    /* effective area: the bore's area k_A pi D^2 / 4 must exceed the rod's */
    if (p[PF_P_area_factor] <= 0.0 ||
        p[PF_P_area_factor] * p[PF_P_bore] * p[PF_P_bore] <= p[PF_P_rod] * p[PF_P_rod])
        return 0;
    /* valve map (checked whatever the law: the defaults are admissible) */
    for (i = 0; i < PF_N_MAP_KNOTS; i++) {
        double cs = p[PF_P_valve_map_CS_00 + i], ce = p[PF_P_valve_map_CE_00 + i];
        if (cs < PF_MAP_C_LOWER || cs > PF_MAP_C_UPPER) return 0;
        if (ce < PF_MAP_C_LOWER || ce > PF_MAP_C_UPPER) return 0;
    }
    for (i = 0; i < 3; i++) {
        double bs = p[PF_P_valve_map_bS_0 + i], be = p[PF_P_valve_map_bE_0 + i];
        if (bs < PF_MAP_B_LOWER || bs > PF_MAP_B_UPPER || bs >= p[PF_P_valve_x_laminar]) return 0;
        if (be < PF_MAP_B_LOWER || be > PF_MAP_B_UPPER || be >= p[PF_P_valve_x_laminar]) return 0;
    }
    return 1;
}

int pf_admissible(const pf_model *m) /* kernel.admissible */
{
    if (!pf_check_parameters(m->p)) return 0;
    /* a first-order valve's rate is (u_cmd - u) / tau: tau must be > 0 */
    if (m->valve_order == 1 && !(m->p[PF_P_valve_time_constant] > 0.0)) return 0;
    return 1;
}

/* ---------------------------------------------------------------- valve */

static void laminar_tail(double b, double m, double x_lam, double *a, double *c)
{ /* physics.valve.laminar_tail */
    double s_l = (x_lam - b) / (1.0 - b);
    double base = 1.0 - s_l * s_l;
    double phi_l = m == 0.5 ? sqrt(base) : pow(base, m);
    double dphi_l = -2.0 * m * s_l / (1.0 - b) * phi_l / base;
    double s = 1.0 - x_lam;
    *a = 2.0 * phi_l / s + dphi_l;
    *c = (phi_l - *a * s) / (s * s);
}

static double phi_fn(double x, double b, double inv_1mb, double m, double x_lam, double a,
                     double c)
{ /* physics.valve._phi */
    double s, base, z;
    if (x <= b) return 1.0;
    if (x < x_lam) {
        s = (x - b) * inv_1mb;
        base = 1.0 - s * s;
        return m == 0.5 ? sqrt(base) : pow(base, m);
    }
    z = 1.0 - x;
    return a * z + c * z * z;
}

static double open_fn(double u, double overlap, double inv_range)
{ /* physics.valve._open */
    double z = u - overlap, t, frac;
    const double eps = PF_OPENING_SMOOTHING;
    if (z <= -eps) return 0.0;
    if (z < eps) {
        t = (z + eps) / (2.0 * eps);
        z = 2.0 * eps * t * t * t * (1.0 - 0.5 * t);
    }
    frac = z * inv_range;
    return frac < 1.0 ? frac : 1.0;
}

static double shaped(double fraction, double n, double knee)
{ /* physics.valve._shaped */
    double s;
    if (fraction <= 0.0) return fraction;
    s = n == 1.0 ? fraction : pow(fraction, n);
    if (knee == 1.0) return s;
    return 1.0 - pow(1.0 - s, knee);
}

static void valve_flows(const pf_model *m, double u, double pres, double inv_pres, double temp,
                        double rt, double p_supply, double inv_p_supply, double *q_net,
                        double *h_in, double *q_supply)
{ /* physics.valve.flows_core */
    double u_c = u - m->v_null; /* the command from the spool's null */
    double z = u_c * m->v_iw;
    double sig_s = 0.5 * (1.0 + z / sqrt(1.0 + z * z));
    double o_s = shaped(open_fn(u_c, m->v_over, m->v_irange), m->v_ns, m->v_ks);
    double o_e = shaped(open_fn(-u_c, m->v_over, m->v_irange_e), m->v_ne, m->v_ke);
    double c_s = m->v_cs * o_s + m->v_leak2 * sig_s;
    double c_e = m->v_ce * o_e + m->v_leak2 * (1.0 - sig_s);
    const double k = PF_RHO0;
    double phi, q_s, t_s, q_e, t_e, p_e;
    if (p_supply >= pres) {
        phi = phi_fn(pres * inv_p_supply, m->v_bs, m->v_ibs, m->v_m, m->v_xlam, m->v_as, m->v_qs);
        q_s = c_s * k * p_supply * m->v_rta * phi;
        t_s = m->v_ta;
    } else {
        phi = phi_fn(p_supply * inv_pres, m->v_bs, m->v_ibs, m->v_m, m->v_xlam, m->v_as, m->v_qs);
        q_s = -c_s * k * pres * rt * phi;
        t_s = temp;
    }
    p_e = m->v_pe;
    if (pres >= p_e) {
        phi = phi_fn(p_e * inv_pres, m->v_be, m->v_ibe, m->v_m, m->v_xlam, m->v_ae, m->v_qe);
        q_e = c_e * k * pres * rt * phi;
        t_e = temp;
    } else {
        phi = phi_fn(pres * m->v_ipe, m->v_be, m->v_ibe, m->v_m, m->v_xlam, m->v_ae, m->v_qe);
        q_e = -c_e * k * p_e * m->v_rta * phi;
        t_e = m->v_ta;
    }
    *q_net = q_s - q_e;
    *h_in = q_s * t_s - q_e * t_e;
    *q_supply = q_s;
}

/* ------------------------------------------------------------ valve map */

static double flow_function(double x, double b, double m, double x_lam)
{ /* physics.valve.flow_function (tail coefficients computed per call) */
    double s, base, a, c, z;
    if (x <= b) return 1.0;
    if (x < x_lam) {
        s = (x - b) / (1.0 - b);
        base = 1.0 - s * s;
        return m == 0.5 ? sqrt(base) : pow(base, m);
    }
    laminar_tail(b, m, x_lam, &a, &c);
    z = 1.0 - x;
    return a * z + c * z * z;
}

static void pchip_slopes(const double *x, const double *y, double *slopes, int n)
{ /* physics.valve_map.pchip_slopes */
    int k;
    double h0, h1, d0, d1, w1, w2;
    slopes[0] = 0.0;
    slopes[n - 1] = 0.0;
    for (k = 1; k < n - 1; k++) {
        h0 = x[k] - x[k - 1];
        h1 = x[k + 1] - x[k];
        d0 = (y[k] - y[k - 1]) / h0;
        d1 = (y[k + 1] - y[k]) / h1;
        if (d0 * d1 <= 0.0) {
            slopes[k] = 0.0;
        } else {
            w1 = 2.0 * h1 + h0;
            w2 = h1 + 2.0 * h0;
            slopes[k] = (w1 + w2) / (w1 / d0 + w2 / d1);
        }
    }
}

static void fill_path(const double *u, const double *c, double *ck, double *coef)
{ /* physics.valve_map._fill_path */
    const int n = PF_N_MAP_KNOTS;
    double logc[PF_N_MAP_KNOTS], slopes[PF_N_MAP_KNOTS], h, delta, m0, m1;
    int k;
    for (k = 0; k < n; k++) {
        ck[k] = c[k];
        logc[k] = log(c[k]);
    }
    pchip_slopes(u, logc, slopes, n);
    for (k = 0; k < n - 1; k++) {
        h = u[k + 1] - u[k];
        delta = logc[k + 1] - logc[k];
        m0 = h * slopes[k];
        m1 = h * slopes[k + 1];
        coef[3 * k] = m0;
        coef[3 * k + 1] = 3.0 * delta - 2.0 * m0 - m1;
        coef[3 * k + 2] = m0 + m1 - 2.0 * delta;
    }
}

static void map_constants(pf_model *m)
{ /* physics.valve_map.map_constants */
    static const double knots[PF_N_MAP_KNOTS] = PF_MAP_KNOTS_INIT;
    const int n = PF_N_MAP_KNOTS;
    const double *p = m->p, *b_s = p + PF_P_valve_map_bS_0, *b_e = p + PF_P_valve_map_bE_0;
    double u_sat = p[PF_P_valve_u_sat], cs[PF_N_MAP_KNOTS], ce[PF_N_MAP_KNOTS];
    int k;
    for (k = 0; k < n; k++) {
        m->vm_u[k] = knots[k] * u_sat;
        cs[k] = p[PF_P_valve_map_CS_00 + k] > PF_MAP_FLOOR ? p[PF_P_valve_map_CS_00 + k]
                                                           : PF_MAP_FLOOR;
        ce[k] = p[PF_P_valve_map_CE_00 + k] > PF_MAP_FLOOR ? p[PF_P_valve_map_CE_00 + k]
                                                           : PF_MAP_FLOOR;
    }
    for (k = 1; k < n; k++) {
        if (cs[k] < cs[k - 1]) cs[k] = cs[k - 1];
    }
    for (k = n - 2; k >= 0; k--) {
        if (ce[k] < ce[k + 1]) ce[k] = ce[k + 1];
    }
    m->vm_iusat = 1.0 / u_sat;
    m->vm_cs_lo = cs[0];
    m->vm_cs_hi = cs[n - 1];
    m->vm_ce_lo = ce[0];
    m->vm_ce_hi = ce[n - 1];
    for (k = 0; k < 3; k++) {
        m->vm_bs[k] = b_s[k];
        m->vm_be[k] = b_e[k];
    }
    m->vm_dbs[0] = (b_s[1] - b_s[0]) / PF_MAP_B1;
    m->vm_dbs[1] = (b_s[2] - b_s[1]) / (1.0 - PF_MAP_B1);
    m->vm_dbe[0] = (b_e[1] - b_e[0]) / PF_MAP_B1;
    m->vm_dbe[1] = (b_e[2] - b_e[1]) / (1.0 - PF_MAP_B1);
    for (k = 0; k < n - 1; k++) m->vm_ih[k] = 1.0 / (m->vm_u[k + 1] - m->vm_u[k]);
    fill_path(m->vm_u, cs, m->vm_ck_s, m->vm_coef_s);
    fill_path(m->vm_u, ce, m->vm_ck_e, m->vm_coef_e);
}

static void map_conductances(const pf_model *m, double u, double *c_s, double *c_e)
{ /* physics.valve_map.map_conductances */
    int k = PF_MAP_CENTRE_KNOT;
    double t;
    const double *j;
    if (u <= m->vm_u[0]) {
        *c_s = m->vm_cs_lo;
        *c_e = m->vm_ce_lo;
        return;
    }
    if (u >= m->vm_u[PF_N_MAP_KNOTS - 1]) {
        *c_s = m->vm_cs_hi;
        *c_e = m->vm_ce_hi;
        return;
    }
    if (u >= 0.0) {
        while (u >= m->vm_u[k + 1]) k++;
    } else {
        k--;
        while (u < m->vm_u[k]) k--;
    }
    t = (u - m->vm_u[k]) * m->vm_ih[k];
    j = m->vm_coef_s + 3 * k;
    *c_s = m->vm_ck_s[k] * exp(t * (j[0] + t * (j[1] + t * j[2])));
    j = m->vm_coef_e + 3 * k;
    *c_e = m->vm_ck_e[k] * exp(t * (j[0] + t * (j[1] + t * j[2])));
}

static double map_ratio(double f, const double *b, const double *db)
{ /* physics.valve_map._ratio */
    if (f <= 0.0) return b[0];
    if (f < PF_MAP_B1) return b[0] + f * db[0];
    if (f < 1.0) return b[1] + (f - PF_MAP_B1) * db[1];
    return b[2];
}

static void valve_flows_map(const pf_model *m, double u, double pres, double inv_pres,
                            double temp, double rt, double p_supply, double inv_p_supply,
                            double *q_net, double *h_in, double *q_supply)
{ /* physics.valve_map.flows_core_map */
    double c_s, c_e, f = u * m->vm_iusat, b_s, b_e, q_s, t_s, q_e, t_e, p_e = m->v_pe;
    const double k = PF_RHO0, mm = m->v_m, x_lam = m->v_xlam;
    map_conductances(m, u, &c_s, &c_e);
    b_s = map_ratio(f, m->vm_bs, m->vm_dbs);
    b_e = map_ratio(-f, m->vm_be, m->vm_dbe);
    if (p_supply >= pres) {
        q_s = c_s * k * p_supply * m->v_rta * flow_function(pres * inv_p_supply, b_s, mm, x_lam);
        t_s = m->v_ta;
    } else {
        q_s = -c_s * k * pres * rt * flow_function(p_supply * inv_pres, b_s, mm, x_lam);
        t_s = temp;
    }
    if (pres >= p_e) {
        q_e = c_e * k * pres * rt * flow_function(p_e * inv_pres, b_e, mm, x_lam);
        t_e = temp;
    } else {
        q_e = -c_e * k * p_e * m->v_rta * flow_function(pres * m->v_ipe, b_e, mm, x_lam);
        t_e = m->v_ta;
    }
    *q_net = q_s - q_e;
    *h_in = q_s * t_s - q_e * t_e;
    *q_supply = q_s;
}

static void valve(const pf_model *m, double u, double pres, double inv_pres, double temp,
                  double rt, double p_supply, double inv_p_supply, double *q_net, double *h_in,
                  double *q_supply)
{ /* kernel._valve: the configured valve law (kernel.part_valve: one from outside) */
    if (PF_PART_VALVE) {
        double out[3];
        (void)inv_pres;
        (void)rt;
        (void)inv_p_supply;
        pf_part_valve(u, pres, temp, p_supply, m->p, out);
        *q_net = out[0];
        *h_in = out[1];
        *q_supply = out[2];
    } else if (m->valve_map)
        valve_flows_map(m, u, pres, inv_pres, temp, rt, p_supply, inv_p_supply, q_net, h_in,
                        q_supply);
    else
        valve_flows(m, u, pres, inv_pres, temp, rt, p_supply, inv_p_supply, q_net, h_in,
                    q_supply);
}

/* -------------------------------------------------------------- derived */

void pf_derive(pf_model *m) /* kernel.derive: valve_constants and map_constants */
{
    const double *p = m->p;
    double bore = p[PF_P_bore], rod = p[PF_P_rod], length = p[PF_P_characteristic_length];
    double s_p = 0.25 * M_PI * bore * bore;
    double s_n = 0.25 * M_PI * (bore * bore - rod * rod);
    m->s_p = s_p;
    m->s_n = s_n;
    m->f_ext = p[PF_P_exhaust_pressure] * (s_p - s_n) + p[PF_P_external_force] +
               p[PF_P_moving_mass] * PF_G0 * sin(p[PF_P_mounting_angle]);
    m->mu = viscosity(p[PF_P_wall_temperature]);
    m->k_air = conductivity(p[PF_P_wall_temperature]);
    m->lam_c = p[PF_P_xi] * m->k_air / length;
    m->gr_c = PF_G0 * (length * length * length) / ((PF_R_AIR * m->mu) * (PF_R_AIR * m->mu));
    /* heads, piston faces and rod counted with the share heat_area_ends */
    double ends = p[PF_P_heat_area_ends], rod_e = ends * rod;
    m->a0p = 2.0 * ends * s_p + M_PI * bore * p[PF_P_dead_volume_P] / s_p;
    m->cap = M_PI * bore;
    m->a0n = 2.0 * ends * s_n + M_PI * (bore + rod_e) * p[PF_P_dead_volume_N] / s_n;
    m->can = M_PI * (bore + rod_e);
    { /* the effective bore D sqrt(k_A) of effect effective_area, the rod unchanged */
        double k_a = p[PF_P_area_factor];
        double bore_k = k_a > 0.0 ? bore * sqrt(k_a) : bore;
        double s_pk = 0.25 * M_PI * bore_k * bore_k;
        double s_nk = 0.25 * M_PI * (bore_k * bore_k - rod * rod);
        m->s_pk = s_pk;
        m->s_nk = s_nk;
        m->a0pk = 2.0 * ends * s_pk + M_PI * bore_k * p[PF_P_dead_volume_P] / s_pk;
        m->capk = M_PI * bore_k;
        m->a0nk = s_nk > 0.0
                      ? 2.0 * ends * s_nk + M_PI * (bore_k + rod_e) * p[PF_P_dead_volume_N] / s_nk
                      : 0.0;
        m->cank = M_PI * (bore_k + rod_e);
    }
    m->inv_ps = 1.0 / p[PF_P_supply_pressure];
    m->inv_m = 1.0 / p[PF_P_moving_mass];
    m->z_rate = INFINITY;
    /* valve constants */
    m->v_ns = p[PF_P_valve_n_supply];
    m->v_ne = p[PF_P_valve_n_exhaust];
    m->v_ks = p[PF_P_valve_knee_supply];
    m->v_ke = p[PF_P_valve_knee_exhaust];
    m->v_cs = p[PF_P_valve_C_supply];
    m->v_ce = p[PF_P_valve_C_exhaust];
    m->v_bs = p[PF_P_valve_b_supply];
    m->v_be = p[PF_P_valve_b_exhaust];
    m->v_ibs = 1.0 / (1.0 - m->v_bs);
    m->v_ibe = 1.0 / (1.0 - m->v_be);
    m->v_m = p[PF_P_valve_m];
    m->v_xlam = p[PF_P_valve_x_laminar];
    laminar_tail(m->v_bs, m->v_m, m->v_xlam, &m->v_as, &m->v_qs);
    laminar_tail(m->v_be, m->v_m, m->v_xlam, &m->v_ae, &m->v_qe);
    m->v_over = p[PF_P_valve_overlap];
    m->v_irange = 1.0 / (p[PF_P_valve_full_supply] * p[PF_P_valve_u_sat] - p[PF_P_valve_overlap]);
    m->v_null = p[PF_P_valve_null_offset];
    m->v_irange_e =
        1.0 / (p[PF_P_valve_full_exhaust] * p[PF_P_valve_u_sat] - p[PF_P_valve_overlap]);
    m->v_leak2 = 2.0 * p[PF_P_valve_C_leak];
    m->v_iw = 1.0 / p[PF_P_valve_leak_width];
    m->v_pe = p[PF_P_exhaust_pressure];
    m->v_ipe = 1.0 / p[PF_P_exhaust_pressure];
    m->v_ta = p[PF_P_ambient_temperature];
    m->v_rta = sqrt(PF_T_REF / p[PF_P_ambient_temperature]);
    map_constants(m);
}

/* ---------------------------------------------------------- heat, chamber */

static double heat_coefficient(const pf_model *m, double pres, double temp, double t_wall)
{ /* kernel.heat_coefficient, physics.heat.convection_coefficient(_scaled) */
    const double *p = m->p;
    double gr, len;
    if (m->heat == 1) return p[PF_P_lambda];
    if (m->heat > 2) return pf_part_heat(p, pres, temp, t_wall); /* kernel.part_heat */
    if (m->heat != 2) return 0.0;
    if (m->sutherland) {
        double mu = viscosity(temp), k_air = conductivity(temp);
        len = p[PF_P_characteristic_length];
        gr = PF_G0 * pow(len, 3.0) * fabs(t_wall - temp) * pow(pres, 2.0) /
             (pow(PF_R_AIR, 2.0) * pow(mu, 2.0) * pow(temp, 3.0));
        if (gr <= 0.0) return 0.0;
        return p[PF_P_xi] * k_air / len * exp(p[PF_P_beta] * log(gr));
    }
    gr = m->gr_c * fabs(t_wall - temp) * pres * pres / (temp * temp * temp);
    if (gr <= 0.0) return 0.0;
    return m->lam_c * exp(p[PF_P_beta] * log(gr));
}

static void chamber_rates(int heat, double k_poly, double t_0, double pres, double inv_p,
                          double temp, double vol, double dvol, double q_net, double h_net,
                          double q_wall, double *dp, double *dt)
{ /* kernel.chamber_rates */
    double inv_v = 1.0 / vol;
    if (heat == 0) {
        *dp = k_poly * (PF_R_AIR * t_0 * q_net - pres * dvol) * inv_v;
        *dt = 0.0;
        return;
    }
    *dp = (PF_GAMMA * PF_R_AIR * h_net - PF_GAMMA * pres * dvol + (PF_GAMMA - 1.0) * q_wall) *
          inv_v;
    *dt = temp * (*dp * inv_p + (dvol - PF_R_AIR * temp * q_net * inv_p) * inv_v);
}

/* ------------------------------------------------------------- friction */

static double sliding_friction(double v, int direction, double f_s, double f_c, double b,
                               double v_st)
{ /* physics.friction.sliding_friction */
    double r = v / v_st;
    return direction * (f_c + (f_s - f_c) * exp(-r * r)) + b * v;
}

static void lugre_friction(double v, double z, double f_s, double f_c, double b, double v_st,
                           double sigma0, double sigma1, double max_rate, double *dz, double *f)
{ /* physics.friction.lugre_friction */
    double r = v / v_st;
    double g = f_c + (f_s - f_c) * exp(-r * r);
    double s_v, z_ss;
    if (g < PF_LUGRE_MIN_LEVEL) g = PF_LUGRE_MIN_LEVEL;
    s_v = sigma0 * fabs(v);
    if (s_v <= max_rate * g) {
        *dz = v - s_v * z / g;
    } else {
        z_ss = v > 0.0 ? g / sigma0 : -g / sigma0;
        *dz = max_rate * (z_ss - z);
    }
    *f = sigma0 * z + sigma1 * *dz + b * v;
}

static int next_mode(double f_drive, double f_static) /* physics.friction.next_mode */
{
    if (f_drive > f_static) return 1;
    if (f_drive < -f_static) return -1;
    return 0;
}

static double end_stop_force(double y, double v, double stroke, double k, double c)
{ /* physics.friction.end_stop_force */
    double f;
    if (y < 0.0) {
        f = -k * y - c * v;
        return f > 0.0 ? f : 0.0;
    }
    if (y > stroke) {
        f = -k * (y - stroke) - c * v;
        return f < 0.0 ? f : 0.0;
    }
    return 0.0;
}

/* ---------------------------------------------------------------- rhs */

void pf_rhs(const pf_model *m, const double *x, int mode, double u_p_cmd, double u_n_cmd,
            double *dx, double *aux)
{ /* kernel.rhs, moving piston, with the optional effects */
    const double *p = m->p;
    int i, heat = m->heat, order = m->valve_order;
    double y = x[PF_X_y], v = x[PF_X_v], p_n = x[PF_X_p_N], p_p = x[PF_X_p_P];
    double t_n = x[PF_X_T_N], t_p = x[PF_X_T_P];
    double t_amb = p[PF_P_ambient_temperature], p_e = p[PF_P_exhaust_pressure];
    double u_p, u_n, tau, wn, z2;
    double s_p = m->area ? m->s_pk : m->s_p, s_n = m->area ? m->s_nk : m->s_n;
    double stroke = p[PF_P_stroke];
    double v_p, v_n, dv_p, dv_n, inv_pp, inv_pn, rt_p, rt_n, p_s, inv_ps;
    double q_p, h_p, qs_p, q_n, h_n, qs_n, qe_total, q_draw, q_l, t_l, q_l2, t_l2;
    double tw_p, tw_n, lam_p, lam_n, a_p, a_n, qw_p, qw_n, c_w, h_o, t_0, k_poly;
    double dp_p, dt_p, dp_n, dt_n, f_stop, f_drive, f_s, f_c, f_f, dz, extra, f_part = 0.0;

    if (!m->wall_mass && order == 0) {
        for (i = 8; i < PF_NX; i++) dx[i] = 0.0;
    }
    for (i = PF_X_e_0; i < PF_NX; i++) dx[i] = 0.0; /* outside effects' states (below) */

    /* valve commands: static, or spool dynamics (effect valve_dynamics) */
    if (order < 2) {
        dx[PF_X_dus_P] = 0.0;
        dx[PF_X_dus_N] = 0.0;
    }
    if (order == 0) {
        dx[PF_X_us_P] = 0.0;
        dx[PF_X_us_N] = 0.0;
        u_p = u_p_cmd;
        u_n = u_n_cmd;
    } else {
        u_p = x[PF_X_us_P];
        u_n = x[PF_X_us_N];
        if (order == 1) {
            tau = p[PF_P_valve_time_constant];
            dx[PF_X_us_P] = (u_p_cmd - u_p) / tau;
            dx[PF_X_us_N] = (u_n_cmd - u_n) / tau;
        } else {
            wn = p[PF_P_valve_natural_frequency];
            z2 = 2.0 * p[PF_P_valve_damping_ratio] * wn;
            dx[PF_X_us_P] = x[PF_X_dus_P];
            dx[PF_X_us_N] = x[PF_X_dus_N];
            dx[PF_X_dus_P] = wn * wn * (u_p_cmd - u_p) - z2 * x[PF_X_dus_P];
            dx[PF_X_dus_N] = wn * wn * (u_n_cmd - u_n) - z2 * x[PF_X_dus_N];
        }
    }

    /* geometry */
    v_p = p[PF_P_dead_volume_P] + s_p * y;
    v_n = p[PF_P_dead_volume_N] + s_n * (stroke - y);
    dv_p = s_p * v;
    dv_n = -s_n * v;

    /* valve flows (ISO 6358), optional supply-line pressure drop */
    inv_pp = 1.0 / p_p;
    inv_pn = 1.0 / p_n;
    rt_p = sqrt(PF_T_REF / t_p);
    rt_n = sqrt(PF_T_REF / t_n);
    p_s = p[PF_P_supply_pressure];
    inv_ps = m->inv_ps;
    valve(m, u_p, p_p, inv_pp, t_p, rt_p, p_s, inv_ps, &q_p, &h_p, &qs_p);
    valve(m, u_n, p_n, inv_pn, t_n, rt_n, p_s, inv_ps, &q_n, &h_n, &qs_n);
    if (m->supply_drop) {
        q_draw = qs_p + qs_n;
        if (q_draw < 0.0) q_draw = 0.0;
        p_s = p_s - p[PF_P_supply_line_resistance] * q_draw;
        if (p_s < p_e) p_s = p_e;
        inv_ps = 1.0 / p_s;
        valve(m, u_p, p_p, inv_pp, t_p, rt_p, p_s, inv_ps, &q_p, &h_p, &qs_p);
        valve(m, u_n, p_n, inv_pn, t_n, rt_n, p_s, inv_ps, &q_n, &h_n, &qs_n);
    }
    qe_total = (qs_p - q_p) + (qs_n - q_n);
    aux[PF_A_QN] = q_n;
    aux[PF_A_QP] = q_p;
    aux[PF_A_UN] = u_n;
    aux[PF_A_UP] = u_p;

    /* leakages (effects) */
    if (m->chamber_leak) {
        q_l = p[PF_P_chamber_leak_conductance] * (p_p - p_n);
        t_l = q_l > 0.0 ? t_p : t_n;
        q_p -= q_l;
        h_p -= q_l * t_l;
        q_n += q_l;
        h_n += q_l * t_l;
    }
    if (m->external_leak) {
        q_l = p[PF_P_external_leak_conductance] * (1.0 + p[PF_P_external_leak_split]) * (p_p - p_e);
        t_l = q_l > 0.0 ? t_p : t_amb;
        q_p -= q_l;
        h_p -= q_l * t_l;
        q_l2 = p[PF_P_external_leak_conductance] * (1.0 - p[PF_P_external_leak_split]) * (p_n - p_e);
        t_l2 = q_l2 > 0.0 ? t_n : t_amb;
        q_n -= q_l2;
        h_n -= q_l2 * t_l2;
        qe_total += q_l + q_l2;
    }
    if (PF_PART_EFFECTS > 0) { /* effects from outside the package (kernel.part_effects) */
        double e[6];
        pf_part_effects(x, p, e);
        q_p += e[0];
        h_p += e[1];
        q_n += e[2];
        h_n += e[3];
        qe_total += e[4];
        f_part = e[5];
        pf_part_effect_rates(x, p, dx);
    }

    /* wall heat exchange (paper eqs. 6-8) */
    if (m->wall_mass) {
        tw_p = x[PF_X_Tw_P];
        tw_n = x[PF_X_Tw_N];
    } else {
        tw_p = p[PF_P_wall_temperature];
        tw_n = p[PF_P_wall_temperature];
    }
    lam_p = heat_coefficient(m, p_p, t_p, tw_p);
    lam_n = heat_coefficient(m, p_n, t_n, tw_n);
    if (m->forced_conv && heat != 0) {
        if (qs_p > 0.0) lam_p += p[PF_P_forced_convection_gain] * qs_p;
        if (qs_n > 0.0) lam_n += p[PF_P_forced_convection_gain] * qs_n;
    }
    if (m->area) {
        a_p = m->a0pk + m->capk * y;
        a_n = m->a0nk + m->cank * (stroke - y);
    } else {
        a_p = m->a0p + m->cap * y;
        a_n = m->a0n + m->can * (stroke - y);
    }
    qw_p = lam_p * a_p * (tw_p - t_p);
    qw_n = lam_n * a_n * (tw_n - t_n);
    aux[PF_A_LAMN] = lam_n;
    aux[PF_A_LAMP] = lam_p;
    dx[PF_X_Tw_P] = 0.0;
    dx[PF_X_Tw_N] = 0.0;
    if (m->wall_mass) {
        c_w = p[PF_P_wall_heat_capacity];
        h_o = p[PF_P_wall_outer_coefficient];
        dx[PF_X_Tw_P] = (lam_p * (t_p - tw_p) + h_o * (t_amb - tw_p)) / c_w;
        dx[PF_X_Tw_N] = (lam_n * (t_n - tw_n) + h_o * (t_amb - tw_n)) / c_w;
    }

    /* chambers */
    t_0 = p[PF_P_wall_temperature];
    k_poly = p[PF_P_k];
    chamber_rates(heat, k_poly, t_0, p_p, inv_pp, t_p, v_p, dv_p, q_p, h_p, qw_p, &dp_p, &dt_p);
    chamber_rates(heat, k_poly, t_0, p_n, inv_pn, t_n, v_n, dv_n, q_n, h_n, qw_n, &dp_n, &dt_n);
    dx[PF_X_p_P] = dp_p;
    dx[PF_X_T_P] = dt_p;
    dx[PF_X_p_N] = dp_n;
    dx[PF_X_T_N] = dt_n;

    /* mechanics (eq. 1) and friction */
    f_stop = end_stop_force(y, v, stroke, p[PF_P_stop_stiffness], p[PF_P_stop_damping]);
    f_drive = s_p * p_p - s_n * p_n - m->f_ext + f_stop + f_part;
    f_s = p[PF_P_friction_static];
    f_c = p[PF_P_friction_coulomb];
    if (m->seal) {
        extra = p[PF_P_seal_friction_coefficient] * (p_p + p_n - 2.0 * p_e);
        if (extra > 0.0) {
            f_s += extra;
            f_c += extra;
        }
    }
    if (m->asym) { /* levels times (1 + a s), s the sliding direction */
        double s_dir, scale;
        if (PF_SMOOTH(m))
            s_dir = v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0);
        else if (mode == 0)
            s_dir = f_drive > 0.0 ? 1.0 : (f_drive < 0.0 ? -1.0 : 0.0);
        else
            s_dir = (double)mode;
        scale = 1.0 + p[PF_P_friction_asymmetry] * s_dir;
        f_s *= scale;
        f_c *= scale;
    }
    if (m->lugre) {
        lugre_friction(v, x[PF_X_z_f], f_s, f_c, p[PF_P_friction_viscous],
                       p[PF_P_stribeck_velocity], p[PF_P_friction_stiffness],
                       p[PF_P_friction_damping], m->z_rate, &dz, &f_f);
        dx[PF_X_y] = v;
        dx[PF_X_v] = (f_drive - f_f) * m->inv_m;
        dx[PF_X_z_f] = dz;
    } else if (PF_SMOOTH(m)) { /* kernel.part_friction, part_friction_rate */
        f_f = pf_part_friction(v, f_s, f_c, x, p);
        dx[PF_X_y] = v;
        dx[PF_X_v] = (f_drive - f_f) * m->inv_m;
        dx[PF_X_z_f] = pf_part_friction_rate(v, f_s, f_c, x, p, m->z_rate);
    } else if (mode == 0) {
        f_f = f_drive;
        dx[PF_X_y] = 0.0;
        dx[PF_X_v] = 0.0;
        dx[PF_X_z_f] = 0.0;
    } else {
        if (PF_PART_FRICTION_STUCK) /* kernel.part_friction_sliding */
            f_f = pf_part_friction_sliding(v, (double)mode, f_s, f_c, x, p);
        else
            f_f = sliding_friction(v, mode, f_s, f_c, p[PF_P_friction_viscous],
                                   p[PF_P_stribeck_velocity]);
        dx[PF_X_y] = v;
        dx[PF_X_v] = (f_drive - f_f) * m->inv_m;
        dx[PF_X_z_f] = 0.0;
    }
    aux[PF_A_FF] = f_f;
    aux[PF_A_FD] = f_drive;
    aux[PF_A_FS] = f_s;
    dx[PF_X_m_supply] = qs_p + qs_n;
    dx[PF_X_m_exhaust] = qe_total;
}

/* ----------------------------------------------------------- integrator */

static void commands(const pf_inputs *in, double w, double *u_p, double *u_n)
{ /* kernel.commands, open loop: linear in the step's fraction w */
    *u_p = in->u_p0 + w * in->du_p;
    *u_n = in->u_n0 + w * in->du_n;
}

typedef struct {
    double kk[3][PF_NX];
    double xs[PF_NX];
    double dx[PF_NX];
    double aux[PF_NAUX];
} pf_work;

static int active_states(const pf_model *m)
{ /* kernel.active_states */
    return (m->wall_mass || m->valve_order > 0 || PF_SMOOTH(m) || PF_PART_EFFECTS > 0) ? PF_NX
                                                                                       : 8;
}

static void rk_step(const pf_model *m, const double *x, int mode, const pf_inputs *in, double w0,
                    double dw, double h, pf_work *wk, double *xn)
{ /* kernel.rk_step, Kutta's third-order method written out */
    int i, nx = active_states(m);
    double u_p, u_n, hh = 0.5 * h, h6 = h / 6.0;
    double *k1 = wk->kk[0], *k2 = wk->kk[1], *k3 = wk->kk[2], *xs = wk->xs;
    for (i = nx; i < PF_NX; i++) {
        xs[i] = x[i];
        xn[i] = x[i];
    }
    commands(in, w0, &u_p, &u_n);
    pf_rhs(m, x, mode, u_p, u_n, k1, wk->aux);
    for (i = 0; i < nx; i++) xs[i] = x[i] + hh * k1[i];
    commands(in, w0 + 0.5 * dw, &u_p, &u_n);
    pf_rhs(m, xs, mode, u_p, u_n, k2, wk->aux);
    for (i = 0; i < nx; i++) xs[i] = x[i] + h * (2.0 * k2[i] - k1[i]);
    commands(in, w0 + dw, &u_p, &u_n);
    pf_rhs(m, xs, mode, u_p, u_n, k3, wk->aux);
    for (i = 0; i < nx; i++) xn[i] = x[i] + h6 * (k1[i] + 4.0 * k2[i] + k3[i]);
}

static double event_function(int kind, const double *xe, const double *aux)
{ /* kernel._event_function */
    if (kind == 0) return xe[PF_X_v];
    return fabs(aux[PF_A_FD]) - aux[PF_A_FS];
}

static double locate_event(const pf_model *m, int kind, double g0, double g1, const double *x,
                           int mode, const pf_inputs *in, double w0, double dw, double h,
                           pf_work *wk, double *xe)
{ /* kernel.locate_event: Illinois iterations on Runge-Kutta sub-steps */
    double lo = 0.0, g_lo = g0, hi = 1.0, g_hi = g1, theta, g, tol, u_p, u_n;
    int side = 0, it;
    theta = g_lo != g_hi ? g_lo / (g_lo - g_hi) : 0.0;
    for (it = 0; it < 8; it++) {
        rk_step(m, x, mode, in, w0, theta * dw, theta * h, wk, xe);
        commands(in, w0 + theta * dw, &u_p, &u_n);
        pf_rhs(m, xe, mode, u_p, u_n, wk->dx, wk->aux);
        g = event_function(kind, xe, wk->aux);
        tol = kind == 0 ? 1e-12 : 1e-9;
        if (fabs(g) <= tol || hi - lo < 1e-12) return theta;
        if ((g > 0.0) == (g_lo > 0.0)) {
            lo = theta;
            g_lo = g;
            if (side == -1) g_hi *= 0.5;
            side = -1;
        } else {
            hi = theta;
            g_hi = g;
            if (side == 1) g_lo *= 0.5;
            side = 1;
        }
        theta = lo - g_lo * (hi - lo) / (g_hi - g_lo);
    }
    rk_step(m, x, mode, in, w0, theta * dw, theta * h, wk, xe);
    commands(in, w0 + theta * dw, &u_p, &u_n);
    pf_rhs(m, xe, mode, u_p, u_n, wk->dx, wk->aux);
    return theta;
}

static double initial_deflection(const pf_model *m, const double *x, double f_drive)
{ /* kernel.initial_deflection */
    const double *p = m->p;
    double f_s = p[PF_P_friction_static], f_c = p[PF_P_friction_coulomb];
    double v = x[PF_X_v], r, g, z_max, z, extra;
    if (m->seal) {
        extra = p[PF_P_seal_friction_coefficient] *
                (x[PF_X_p_P] + x[PF_X_p_N] - 2.0 * p[PF_P_exhaust_pressure]);
        if (extra > 0.0) {
            f_s += extra;
            f_c += extra;
        }
    }
    if (m->asym && v != 0.0) {
        double scale = 1.0 + p[PF_P_friction_asymmetry] * (v > 0.0 ? 1.0 : -1.0);
        f_s *= scale;
        f_c *= scale;
    }
    r = v / p[PF_P_stribeck_velocity];
    g = f_c + (f_s - f_c) * exp(-r * r);
    if (g < PF_LUGRE_MIN_LEVEL) g = PF_LUGRE_MIN_LEVEL;
    z_max = g / p[PF_P_friction_stiffness];
    if (v > 0.0) return z_max;
    if (v < 0.0) return -z_max;
    z = f_drive / p[PF_P_friction_stiffness];
    if (z < -z_max) z = -z_max;
    if (z > z_max) z = z_max;
    return z;
}

void pf_initial_state(const pf_model *m, const double *x0, const pf_inputs *in, pf_state *s)
{ /* kernel._initial_state and the start of kernel.integrate */
    const double *p = m->p;
    double *x = s->x, dx[PF_NX], aux[PF_NAUX], u_p, u_n, t_w = p[PF_P_wall_temperature];
    int i;
    for (i = 0; i < PF_NX; i++) x[i] = x0[i];
    if (m->heat == 0 || !isfinite(x[PF_X_T_N])) x[PF_X_T_N] = t_w;
    if (m->heat == 0 || !isfinite(x[PF_X_T_P])) x[PF_X_T_P] = t_w;
    if (!isfinite(x[PF_X_p_N])) x[PF_X_p_N] = p[PF_P_exhaust_pressure];
    if (!isfinite(x[PF_X_p_P])) x[PF_X_p_P] = p[PF_P_exhaust_pressure];
    if (!isfinite(x[PF_X_v])) x[PF_X_v] = 0.0;
    if (!isfinite(x[PF_X_y])) x[PF_X_y] = 0.0;
    x[PF_X_m_supply] = 0.0;
    x[PF_X_m_exhaust] = 0.0;
    x[PF_X_Tw_N] = t_w;
    x[PF_X_Tw_P] = t_w;
    x[PF_X_us_N] = 0.0;
    x[PF_X_us_P] = 0.0;
    x[PF_X_dus_N] = 0.0;
    x[PF_X_dus_P] = 0.0;
    for (i = PF_X_e_0; i < PF_NX; i++) x[i] = 0.0;
    commands(in, 0.0, &u_p, &u_n);
    if (m->valve_order > 0) {
        x[PF_X_us_P] = u_p;
        x[PF_X_us_N] = u_n;
    }
    s->mode = 0;
    if (m->lugre) {
        if (!isfinite(x[PF_X_z_f])) {
            x[PF_X_z_f] = 0.0;
            pf_rhs(m, x, 0, u_p, u_n, dx, aux);
            x[PF_X_z_f] = initial_deflection(m, x, aux[PF_A_FD]);
        }
    } else {
        x[PF_X_z_f] = 0.0;
    }
    pf_rhs(m, x, 0, u_p, u_n, dx, aux);
    if (!PF_SMOOTH(m)) {
        if (x[PF_X_v] > 0.0)
            s->mode = 1;
        else if (x[PF_X_v] < 0.0)
            s->mode = -1;
        else
            s->mode = next_mode(aux[PF_A_FD], aux[PF_A_FS]);
    }
    s->fd_prev = aux[PF_A_FD];
    s->fs_prev = aux[PF_A_FS];
}

int pf_advance(pf_model *m, pf_state *s, const pf_inputs *in, double H, double h_max)
{ /* one sample interval of kernel.integrate (substeps as simulator.substeps) */
    double n = ceil(H / h_max - 1e-9), jump, h, dw, w0, theta, we, u_p, u_n, e0, e1;
    double *x = s->x, xn[PF_NX], xe[PF_NX];
    int n_sub, j, i, mode = s->mode, direction;
    pf_work wk;
    memset(&wk, 0, sizeof(wk));
    jump = fabs(in->du_p) > fabs(in->du_n) ? fabs(in->du_p) : fabs(in->du_n);
    if (ceil(jump / PF_COMMAND_RESOLUTION) > n) n = ceil(jump / PF_COMMAND_RESOLUTION);
    if (n < 1.0) n = 1.0;
    n_sub = (int)n;
    h = H / n_sub;
    dw = 1.0 / n_sub;
    if (PF_SMOOTH(m)) m->z_rate = PF_LUGRE_RATE_LIMIT / h;
    for (j = 0; j < n_sub; j++) {
        w0 = j * dw;
        rk_step(m, x, mode, in, w0, dw, h, &wk, xn);
        if (PF_SMOOTH(m)) {
            /* no friction modes */
        } else if (mode != 0) {
            if (xn[PF_X_v] * mode <= 0.0) {
                /* the sliding piston came to rest within the step */
                theta = 0.0;
                if (x[PF_X_v] != 0.0) {
                    theta = locate_event(m, 0, x[PF_X_v], xn[PF_X_v], x, mode, in, w0, dw, h, &wk,
                                         xe);
                } else {
                    for (i = 0; i < PF_NX; i++) xe[i] = x[i];
                    commands(in, w0, &u_p, &u_n);
                    pf_rhs(m, xe, 0, u_p, u_n, wk.dx, wk.aux);
                }
                xe[PF_X_v] = 0.0;
                mode = next_mode(wk.aux[PF_A_FD], wk.aux[PF_A_FS]);
                we = w0 + theta * dw;
                rk_step(m, xe, mode, in, we, (1.0 - theta) * dw, (1.0 - theta) * h, &wk, xn);
                if (mode != 0 && xn[PF_X_v] * mode < 0.0) xn[PF_X_v] = 0.0;
            }
        } else if (fabs(wk.aux[PF_A_FD]) > wk.aux[PF_A_FS]) {
            /* the stuck piston breaks away: confirm at the step's end, then locate */
            commands(in, w0 + dw, &u_p, &u_n);
            pf_rhs(m, xn, 0, u_p, u_n, wk.dx, wk.aux);
            e1 = fabs(wk.aux[PF_A_FD]) - wk.aux[PF_A_FS];
            if (e1 > 0.0) {
                direction = wk.aux[PF_A_FD] > 0.0 ? 1 : -1;
                e0 = fabs(s->fd_prev) - s->fs_prev;
                theta = 0.0;
                if (e0 < 0.0) {
                    theta = locate_event(m, 1, e0, e1, x, 0, in, w0, dw, h, &wk, xe);
                } else {
                    for (i = 0; i < PF_NX; i++) xe[i] = x[i];
                }
                mode = direction;
                we = w0 + theta * dw;
                rk_step(m, xe, mode, in, we, (1.0 - theta) * dw, (1.0 - theta) * h, &wk, xn);
            }
        }
        s->fd_prev = wk.aux[PF_A_FD];
        s->fs_prev = wk.aux[PF_A_FS];
        for (i = 0; i < PF_NX; i++) x[i] = xn[i];
    }
    s->mode = mode;
    for (i = 0; i < PF_NX; i++) {
        if (!isfinite(x[i])) return PF_NONFINITE;
    }
    if (x[PF_X_p_P] <= 0.0 || x[PF_X_p_N] <= 0.0 || x[PF_X_T_P] <= 0.0 || x[PF_X_T_N] <= 0.0)
        return PF_NONPHYSICAL;
    return PF_OK;
}
