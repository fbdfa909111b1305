/* The pneumafit actuator model in C: right-hand side and fixed-step integrator.
 *
 * A port of pneumafit.models.kernel (rhs, rk_step with Kutta's third-order
 * method, locate_event, the per-interval loop of integrate) restricted to the
 * structures the FMU supports: ISO 6358 valves or the measured valve map
 * (pneumafit.physics.valve_map), the switch or LuGre friction
 * law, a polytropic, constant-lambda or full-convection heat law, and the
 * optional effects of pneumafit.models.structure.EFFECT_SLOTS. Index names
 * (PF_P_*, PF_X_*) and constants come from pneumafit_config.h, generated from
 * pneumafit.models.layout.
 */
#ifndef PNEUMAFIT_MODEL_H
#define PNEUMAFIT_MODEL_H

#include "pneumafit_config.h"

/* auxiliary values of one right-hand-side evaluation */
enum { PF_A_QN, PF_A_QP, PF_A_UN, PF_A_UP, PF_A_LAMN, PF_A_LAMP, PF_A_FF, PF_A_FD, PF_A_FS,
       PF_NAUX };

/* status codes (as pneumafit.models.kernel) */
enum { PF_OK = 0, PF_NONFINITE = 1, PF_NONPHYSICAL = 2, PF_BAD_PARAMETERS = 3 };

typedef struct {
    /* configuration */
    int heat;       /* 0 polytropic, 1 constant lambda, 2 convection */
    int lugre;      /* 0 switch model, 1 LuGre */
    int sutherland; /* air properties: 0 at the wall temperature, 1 Sutherland at gas T */
    int valve_map;  /* valve law: 0 ISO 6358, 1 measured map */
    /* optional effects (pneumafit.models.structure.EFFECT_SLOTS) */
    int chamber_leak, external_leak, valve_order, wall_mass, forced_conv, supply_drop, seal;
    int asym, area; /* friction_asymmetry, effective_area (physics.seal_effects) */
    /* parameters (SI, layout of pneumafit.models.layout) */
    double p[PF_NP];
    /* derived constants (kernel.derive) */
    double s_p, s_n, f_ext, mu, k_air, lam_c, gr_c, a0p, cap, a0n, can, inv_ps, inv_m, z_rate;
    double s_pk, s_nk, a0pk, capk, a0nk, cank; /* the effective bore (effect effective_area) */
    /* valve constants (physics.valve.valve_constants) */
    double v_cs, v_ce, v_bs, v_be, v_ibs, v_ibe, v_m, v_xlam, v_as, v_qs, v_ae, v_qe;
    double v_over, v_irange, v_irange_e, v_leak2, v_iw, v_pe, v_ipe, v_ta, v_rta, v_ns, v_ne, v_null;
    double v_ks, v_ke; /* knee exponents */
    /* valve-map constants (physics.valve_map.map_constants) */
    double vm_iusat, vm_cs_lo, vm_cs_hi, vm_ce_lo, vm_ce_hi;
    double vm_bs[3], vm_be[3], vm_dbs[2], vm_dbe[2];
    double vm_u[PF_N_MAP_KNOTS], vm_ih[PF_N_MAP_KNOTS - 1];
    double vm_ck_s[PF_N_MAP_KNOTS], vm_ck_e[PF_N_MAP_KNOTS];
    double vm_coef_s[3 * (PF_N_MAP_KNOTS - 1)], vm_coef_e[3 * (PF_N_MAP_KNOTS - 1)];
} pf_model;

/* integrator state carried between communication steps */
typedef struct {
    double x[PF_NX];
    int mode;       /* switch model: 0 stuck, +-1 sliding */
    double fd_prev; /* driving force and static level at the end of the last step */
    double fs_prev;
} pf_state;

/* inputs over one communication step: u(w) = u0 + w du, w in [0, 1] */
typedef struct {
    double u_p0, du_p, u_n0, du_n;
} pf_inputs;

int pf_check_parameters(const double *p);
/* pf_check_parameters and what the configuration needs (kernel.admissible) */
int pf_admissible(const pf_model *m);
void pf_derive(pf_model *m);
void pf_rhs(const pf_model *m, const double *x, int mode, double u_p, double u_n, double *dx,
            double *aux);
/* initial state from the start values (NaN: the kernel's defaults) */
void pf_initial_state(const pf_model *m, const double *x0, const pf_inputs *in, pf_state *s);
/* one communication step of length H split into n equal steps; returns a status code */
int pf_advance(pf_model *m, pf_state *s, const pf_inputs *in, double H, double h_max);

#endif
