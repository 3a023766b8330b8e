/* ftcal_live_selfcheck.h: the self-check of the live step, ftcal.live.consistency's arithmetic in the same order.

   A section of ftcal_live.h (included by it after the drift test, before NAME_retare and the step; not a header of
   its own: it uses the state, FTL_ and FTL_M of ftcal_live.h). One C function per step of ftcal.live.consistency:
   NAME_sc_reset (SelfCheck.reset), NAME_enable_self_check (LiveCalibrator(self_check=True)), NAME_sc_end_hold
   (SelfCheck._end_hold), NAME_sc_observe (SelfCheck.observe_one), NAME_sc_alike (SelfCheck._alike), NAME_sc_check
   (SelfCheck.check with LiveCalibrator._apply_self_check). The state's fields are its sc_* ones; the constants
   (bounds, windows, lock-out time) are the configuration's sc_* fields, filled from ftcal.live.consistency.

   On after NAME_init, as LiveCalibrator's default (s->self_check = 0 turns it off; NAME_enable_self_check again
   after changing noise_variance or walk_variance: they are its bounds). Instead of Python's `tracker` events the
   state counts them (sc_adaptations, sc_lockouts, sc_reacquisitions) with the last one's time, as for the drift
   test's rollbacks, and the rollbacks the walk matching undid (sc_undone). */

static inline void FTL_(sc_reset)(FTL_(state) *s)
{
    int j;
    s->sc_has_window = s->has_time;
    s->sc_window_start = s->last_time;
    s->sc_static = s->sc_gated = s->sc_updated = 0;
    s->sc_nis = 0.0;
    for (j = 0; j < 6; ++j) { s->sc_e2[j] = s->sc_pred[j] = s->sc_diff[j] = 0.0; }
    s->sc_pairs = 0;
    s->sc_has_update = s->has_time;
    s->sc_last_update = s->last_time;
    s->sc_announced = 0;
    s->sc_in_hold = 0;
    s->sc_n_previous = 0;
    s->sc_has_ref = 0;
    s->sc_n_starts = 0;
    s->sc_new_start = 0;
}

/* Turn the self-check on (as LiveCalibrator(self_check=True)), after any change of noise_variance / walk_variance:
   they become its r0 and q0, the bounds it adapts within. */
static inline void FTL_(enable_self_check)(FTL_(state) *s)
{
    memcpy(s->sc_noise0, s->noise_variance, sizeof s->sc_noise0);
    memcpy(s->sc_walk0, s->walk_variance, sizeof s->sc_walk0);
    s->sc_expected_gated = 1.0 - s->cfg.gate_probability;
    s->self_check = 1;
    FTL_(sc_reset)(s);
}

static inline void FTL_(sc_end_hold)(FTL_(state) *s)
{
    int locked = 2 * s->sc_hold_missed > s->sc_hold_n, j, k;
    s->sc_in_hold = 0;
    if (locked && s->sc_hold_last - s->sc_hold_start >= s->cfg.sc_min_hold_s) {
        FTL_(real) norm = 0.0;
        for (j = 0; j < 3; ++j) { norm += s->sc_hold_dir[j] * s->sc_hold_dir[j]; }
        norm = sqrt(norm);
        if (norm == 0.0) { norm = 1.0; }
        if (s->sc_n_previous == FTCAL_LIVE_SC_KEEP_HOLDS) {   /* keep the newest FTCAL_LIVE_SC_KEEP_HOLDS */
            for (k = 1; k < FTCAL_LIVE_SC_KEEP_HOLDS; ++k) {
                memcpy(s->sc_prev_mean[k - 1], s->sc_prev_mean[k], sizeof s->sc_prev_mean[k]);
                memcpy(s->sc_prev_dir[k - 1], s->sc_prev_dir[k], sizeof s->sc_prev_dir[k]);
                s->sc_prev_n[k - 1] = s->sc_prev_n[k];
                s->sc_prev_seconds[k - 1] = s->sc_prev_seconds[k];
                s->sc_prev_end[k - 1] = s->sc_prev_end[k];
            }
            s->sc_n_previous -= 1;
        }
        k = s->sc_n_previous++;
        for (j = 0; j < 6; ++j) { s->sc_prev_mean[k][j] = s->sc_hold_z[j] / (double)s->sc_hold_n; }
        for (j = 0; j < 3; ++j) { s->sc_prev_dir[k][j] = s->sc_hold_dir[j] / norm; }
        s->sc_prev_n[k] = s->sc_hold_n;
        s->sc_prev_seconds[k] = s->sc_hold_last - s->sc_hold_start;
        s->sc_prev_end[k] = s->sc_hold_last;
    } else if (!locked) {
        s->sc_n_previous = 0;
    }
}

/* One sample's sums (SelfCheck.observe_one). */
static inline void FTL_(sc_observe)(FTL_(state) *s, double time, int still, int updated, int gated, const FTL_(real) *z,
                                     const FTL_(real) *e, const FTL_(real) *predicted, const FTL_(real) *innovation_var,
                                     const FTL_(real) *direction)
{
    int j, k;
    if (!s->sc_has_update) {
        s->sc_has_update = 1;
        s->sc_last_update = time;
    }
    if (still) {
        s->sc_static += 1;
        s->sc_gated += (unsigned long)gated;
        if (updated) {
            FTL_(real) nis = 0.0;
            s->sc_updated += 1;
            for (j = 0; j < 6; ++j) { nis += e[j] * e[j] / innovation_var[j]; }
            s->sc_nis += nis;
            for (j = 0; j < 6; ++j) {
                s->sc_e2[j] += e[j] * e[j];
                s->sc_pred[j] += predicted[j];
            }
        }
        if (s->sc_in_hold) {   /* the previous sample was static too: a difference */
            s->sc_pairs += 1;
            for (j = 0; j < 6; ++j) {
                FTL_(real) d = (z[j] - s->sc_last_z[j]) * (z[j] - s->sc_last_z[j]);
                FTL_(real) cap = s->cfg.sc_diff_cap * s->sc_noise0[j];
                s->sc_diff[j] += d < cap ? d : cap;
            }
        }
        memcpy(s->sc_last_z, z, sizeof s->sc_last_z);
        if (!s->sc_in_hold) {
            if (s->sc_has_ref) {   /* a hold starts: its first residual's change since the last static sample */
                if (s->sc_n_starts == FTCAL_LIVE_SC_WALK_KEEP) {   /* keep the newest FTCAL_LIVE_SC_WALK_KEEP */
                    for (k = 1; k < FTCAL_LIVE_SC_WALK_KEEP; ++k) {
                        memcpy(s->sc_start_change[k - 1], s->sc_start_change[k], sizeof s->sc_start_change[k]);
                        memcpy(s->sc_start_var[k - 1], s->sc_start_var[k], sizeof s->sc_start_var[k]);
                        s->sc_start_updated[k - 1] = s->sc_start_updated[k];
                        s->sc_start_gap[k - 1] = s->sc_start_gap[k];
                    }
                    s->sc_n_starts -= 1;
                }
                k = s->sc_n_starts++;
                for (j = 0; j < 6; ++j) {
                    s->sc_start_change[k][j] = (z[j] - s->sc_ref[j]) * (z[j] - s->sc_ref[j]);
                    s->sc_start_var[k][j] = s->sc_ref_var[j];
                }
                s->sc_start_updated[k] = s->sc_ref_updated;
                s->sc_start_gap[k] = time - s->sc_ref_time;
                s->sc_new_start = 1;
            }
            s->sc_in_hold = 1;
            s->sc_hold_n = s->sc_hold_missed = 0;
            for (j = 0; j < 6; ++j) { s->sc_hold_z[j] = 0.0; }
            for (j = 0; j < 3; ++j) { s->sc_hold_dir[j] = 0.0; }
            s->sc_hold_start = time;
        }
        s->sc_hold_n += 1;
        s->sc_hold_missed += !updated;
        for (j = 0; j < 6; ++j) { s->sc_hold_z[j] += z[j]; }
        for (j = 0; j < 3; ++j) { s->sc_hold_dir[j] += direction[j]; }
        s->sc_hold_last = time;
        s->sc_has_ref = 1;
        s->sc_ref_updated = updated;
        s->sc_ref_time = time;
        if (updated) {
            memcpy(s->sc_ref, s->bias, sizeof s->sc_ref);
            memcpy(s->sc_ref_var, s->variance, sizeof s->sc_ref_var);
        } else {
            memcpy(s->sc_ref, z, sizeof s->sc_ref);
        }
        if (updated) { s->sc_last_update = time; }
    } else if (s->sc_in_hold) {
        FTL_(sc_end_hold)(s);
    }
}

/* Whether locked hold k and the current one (mean, unit direction) show the same residual (SelfCheck._alike). */
static inline int FTL_(sc_alike)(const FTL_(state) *s, int k, const FTL_(real) *mean, const FTL_(real) *direction,
                                  double seconds, double time, const FTL_(real) *noise_variance, FTL_(real) *turn,
                                  FTL_(real) *ratio)
{
    double gap;
    FTL_(real) c = 0.0, spread[6], limit;
    int j, a;
    for (j = 0; j < 3; ++j) { c += s->sc_prev_dir[k][j] * direction[j]; }
    *turn = acos(c < -1.0 ? -1.0 : c > 1.0 ? 1.0 : c) * (180.0 / 3.141592653589793);
    if (*turn < s->cfg.sc_min_turn_deg) { return 0; }
    gap = time - s->sc_prev_end[k];
    for (j = 0; j < 6; ++j) {
        double mine = 1.0 / (double)s->sc_hold_n, theirs = 1.0 / (double)s->sc_prev_n[k];
        if (s->cfg.sc_correlation_s / seconds > mine) { mine = s->cfg.sc_correlation_s / seconds; }
        if (s->cfg.sc_correlation_s / s->sc_prev_seconds[k] > theirs) { theirs = s->cfg.sc_correlation_s / s->sc_prev_seconds[k]; }
        spread[j] = noise_variance[j] * (mine + theirs) + s->walk_variance[j] * gap;
    }
    limit = 2.0 * sin(*turn * (3.141592653589793 / 180.0) / 2.0) * s->cfg.sc_turn_share;
    *ratio = 0.0;
    for (a = 0; a < 6; a += 3) {
        FTL_(real) change = 0.0, offset = 0.0, noise = 0.0, bound, r;
        for (j = a; j < a + 3; ++j) {
            change += (mean[j] - s->sc_prev_mean[k][j]) * (mean[j] - s->sc_prev_mean[k][j]);
            offset += (mean[j] - s->bias[j]) * (mean[j] - s->bias[j]);
            noise += spread[j];
        }
        change = sqrt(change);
        offset = sqrt(offset);
        bound = limit * offset;
        if (3.0 * sqrt(noise) > bound) { bound = 3.0 * sqrt(noise); }
        if (change > bound) { return 0; }
        r = change / (offset > 1e-300 ? offset : 1e-300);
        if (r > *ratio) { *ratio = r; }
    }
    return 1;
}

/* q by covariance matching over the hold starts (SelfCheck._match_walk): 1 and *lam, proposal[6] when q must change. */
static inline int FTL_(sc_match_walk)(const FTL_(state) *s, FTL_(real) *lam, FTL_(real) *proposal, int *moves)
{
    FTL_(real) factors[FTCAL_LIVE_SC_WALK_KEEP];
    int i, j, k, m = 0, change = 0;
    for (k = 0; k < s->sc_n_starts; ++k) {
        FTL_(real) total[6], share = 0.0, rho = 0.0;
        double gap = s->sc_start_gap[k];
        for (j = 0; j < 6; ++j) {
            total[j] = (s->sc_start_updated[k] ? s->sc_start_var[k][j] : s->noise_variance[j])
                       + s->walk_variance[j] * gap + s->noise_variance[j];
        }
        for (j = 0; j < 6; ++j) { share += s->walk_variance[j] * gap / total[j]; }
        share /= 6.0;
        if (share >= s->cfg.sc_min_walk_share) {
            for (j = 0; j < 6; ++j) { rho += s->sc_start_change[k][j] / total[j]; }
            rho /= 6.0;
            factors[m++] = 1.0 + (rho / s->cfg.sc_chi2_6_median - 1.0) / share;
        }
    }
    *moves = m;
    if (m < s->cfg.sc_min_walk_starts) { return 0; }
    for (i = 1; i < m; ++i) {   /* insertion sort, then the median */
        FTL_(real) x = factors[i];
        for (k = i - 1; k >= 0 && factors[k] > x; --k) { factors[k + 1] = factors[k]; }
        factors[k + 1] = x;
    }
    *lam = 0.5 * (factors[(m - 1) / 2] + factors[m / 2]);
    if (1.0 / s->cfg.sc_walk_factor < *lam && *lam < s->cfg.sc_walk_factor) { return 0; }
    for (j = 0; j < 6; ++j) {
        FTL_(real) q = *lam * s->walk_variance[j], q0 = s->sc_walk0[j];
        if (q < q0) { q = q0; }
        if (q > s->cfg.sc_q_max * q0) { q = s->cfg.sc_q_max * q0; }
        proposal[j] = q;
        if (fabs(q - s->walk_variance[j]) > 1e-3 * s->walk_variance[j]) { change = 1; }
    }
    return change;
}

/* At a snapshot time, after the drift test (SelfCheck.check and LiveCalibrator._apply_self_check): r by covariance
   matching, the lock-out counted, the bias re-acquired. */
static inline void FTL_(sc_check)(FTL_(state) *s, double time)
{
    int j, k, found = -1;
    double idle, seconds;
    FTL_(real) norm, mean[6], direction[3], turn = 0.0, ratio = 0.0, noise[6];
    memcpy(noise, s->noise_variance, sizeof noise);   /* the re-acquisition below uses r from before this check */
    if (!s->sc_has_window) {
        s->sc_has_window = 1;
        s->sc_window_start = time;
    }
    if (time - s->sc_window_start >= s->cfg.sc_window_s) {
        int updates = s->sc_updated >= (unsigned long)s->cfg.sc_min_window_samples;
        int pairs = s->sc_pairs >= (unsigned long)s->cfg.sc_min_window_samples;
        if (updates || pairs) {
            double n = (double)s->sc_updated;
            FTL_(real) nis = updates ? s->sc_nis / n : 0.0;
            double share = (double)s->sc_gated / (double)(s->sc_static > 0 ? s->sc_static : 1);
            int high = (updates && nis > s->cfg.sc_nis_factor * 6.0)
                       || (share > s->cfg.sc_gated_factor * s->sc_expected_gated && share > 0.01);
            int low = updates && nis < 6.0 / s->cfg.sc_nis_factor;
            if (high || low) {
                FTL_(real) proposal[6];
                int change = 0;
                for (j = 0; j < 6; ++j) {
                    FTL_(real) m = updates ? s->sc_e2[j] / n - s->sc_pred[j] / n : 0.0, r0 = s->sc_noise0[j];
                    if (m < 0.0) { m = 0.0; }
                    if (high && pairs && s->sc_diff[j] / (double)s->sc_pairs / 2.0 > m) {
                        m = s->sc_diff[j] / (double)s->sc_pairs / 2.0;
                    }
                    if (m < r0) { m = r0; }
                    if (m > s->cfg.sc_r_max * r0) { m = s->cfg.sc_r_max * r0; }
                    if (high ? m < s->noise_variance[j] : m > s->noise_variance[j]) { m = s->noise_variance[j]; }
                    proposal[j] = m;
                    if (fabs(m - s->noise_variance[j]) > 1e-3 * s->noise_variance[j]) { change = 1; }
                }
                if (change) {
                    double numbers[5];
                    for (j = 0; j < 6; ++j) {
                        FTL_(real) sd = sqrt(proposal[j]);   /* as Python keeps it: a std, squared when used */
                        s->noise_variance[j] = sd * sd;
                    }
                    s->sc_adaptations += 1;
                    s->sc_last_adapted = time;
                    numbers[0] = updates ? nis : NAN;
                    numbers[1] = (double)s->sc_updated;
                    numbers[2] = (double)s->sc_pairs;
                    numbers[3] = share;
                    numbers[4] = s->sc_expected_gated;
                    FTL_(tracker_event)(s, FTL_M(EVENT_TRACKER_ADAPTED), time, 0, numbers, 5, proposal);
                }
            }
        }
        s->sc_window_start = time;
        s->sc_static = s->sc_gated = s->sc_updated = 0;
        s->sc_nis = 0.0;
        for (j = 0; j < 6; ++j) { s->sc_e2[j] = s->sc_pred[j] = s->sc_diff[j] = 0.0; }
        s->sc_pairs = 0;
    }
    if (s->sc_new_start) {
        FTL_(real) lam, proposal[6], chi2 = 0.0;
        int moves = 0;
        s->sc_new_start = 0;
        if (FTL_(sc_match_walk)(s, &lam, proposal, &moves)) {
            int undo = s->sc_rb_has && s->sc_has_update && s->sc_last_update <= s->sc_rb_time;
            if (undo) {
                for (j = 0; j < 6; ++j) {
                    chi2 += (s->sc_rb_bias[j] - s->sc_rb_b0[j]) * (s->sc_rb_bias[j] - s->sc_rb_b0[j])
                            / (proposal[j] * s->sc_rb_span + s->sc_rb_var[j] + s->sc_rb_p0[j]);
                }
            }
            if (undo && chi2 <= s->drift_chi2) {
                for (j = 0; j < 6; ++j) {   /* no update since a rollback the matched walk explains: undone */
                    s->bias[j] = s->sc_rb_bias[j];
                    s->variance[j] = s->sc_rb_var[j] + proposal[j] * (time - s->sc_rb_time);
                }
                s->sc_undone += 1;
                s->sc_last_undone = time;
                FTL_(tracker_event)(s, FTL_M(EVENT_TRACKER_UNDONE), time, 0, &s->sc_rb_time, 1, 0);
                FTL_(drift_reset)(s);
            } else if (s->sc_has_update && time > s->sc_last_update) {
                double idle0 = time - s->sc_last_update;
                for (j = 0; j < 6; ++j) {   /* the bias walked at the new q since its last update */
                    FTL_(real) more = proposal[j] - s->walk_variance[j];
                    s->variance[j] = s->variance[j] + (more > 0.0 ? more : 0.0) * idle0;
                }
                FTL_(drift_reset)(s);
            }
            memcpy(s->walk_variance, proposal, sizeof proposal);
            s->sc_adaptations += 1;
            s->sc_last_adapted = time;
            {
                double factor = lam;
                FTL_(tracker_event)(s, FTL_M(EVENT_TRACKER_ADAPTED), time, moves, &factor, 1, proposal);
            }
        }
    }
    if (!s->sc_in_hold || !s->sc_has_update || s->sc_hold_last != time) { return; }
    idle = time - s->sc_last_update;
    if (idle <= s->cfg.sc_lock_s) {
        s->sc_announced = 0;
    } else if (!s->sc_announced) {
        s->sc_announced = 1;
        s->sc_lockouts += 1;
        s->sc_last_lockout = time;
        FTL_(tracker_event)(s, FTL_M(EVENT_TRACKER_LOCKED_OUT), time, 0, &idle, 1, 0);
    }
    if (s->sc_n_previous == 0 || time - s->sc_hold_start < s->cfg.sc_min_hold_s || 2 * s->sc_hold_missed <= s->sc_hold_n) {
        return;
    }
    norm = 0.0;
    for (j = 0; j < 3; ++j) { norm += s->sc_hold_dir[j] * s->sc_hold_dir[j]; }
    norm = sqrt(norm);
    if (norm == 0.0) { norm = 1.0; }
    for (j = 0; j < 6; ++j) { mean[j] = s->sc_hold_z[j] / (double)s->sc_hold_n; }
    for (j = 0; j < 3; ++j) { direction[j] = s->sc_hold_dir[j] / norm; }
    seconds = time - s->sc_hold_start;
    for (k = s->sc_n_previous - 1; k >= 0; --k) {
        if (FTL_(sc_alike)(s, k, mean, direction, seconds, time, noise, &turn, &ratio)) {
            found = k;
            break;
        }
    }
    if (found < 0) { return; }
    {
        FTL_(real) moved[6], share[6];
        double span = idle + seconds;
        FTL_(real) force = 0.0, torque = 0.0;
        double numbers[3];
        for (j = 0; j < 6; ++j) { moved[j] = mean[j] - s->bias[j]; }
        numbers[0] = ratio;
        numbers[1] = turn;
        numbers[2] = 0.0;
        for (j = 0; j < 6; ++j) { if (fabs(moved[j]) > numbers[2]) { numbers[2] = fabs(moved[j]); } }
        for (j = 0; j < 3; ++j) { force += moved[j] * moved[j]; }
        for (j = 3; j < 6; ++j) { torque += moved[j] * moved[j]; }
        for (j = 0; j < 6; ++j) { share[j] = (j < 3 ? force : torque) / 3.0; }
        FTL_(real) proposal[6];
        int change = 0;
        if (span < 1e-9) { span = 1e-9; }
        for (j = 0; j < 6; ++j) {
            FTL_(real) q = s->walk_variance[j], m2 = share[j] / span;
            if (m2 > q) { q = m2; }
            if (q > s->cfg.sc_q_max * s->sc_walk0[j]) { q = s->cfg.sc_q_max * s->sc_walk0[j]; }
            proposal[j] = q;
            if (fabs(q - s->walk_variance[j]) > 1e-3 * s->walk_variance[j]) { change = 1; }
        }
        if (change) { memcpy(s->walk_variance, proposal, sizeof proposal); }
        for (j = 0; j < 6; ++j) {
            double mine = 1.0 / (double)s->sc_hold_n;
            if (s->cfg.sc_correlation_s / seconds > mine) { mine = s->cfg.sc_correlation_s / seconds; }
            s->variance[j] = noise[j] * mine;
            s->bias[j] = mean[j];
        }
        FTL_(tracker_event)(s, FTL_M(EVENT_TRACKER_REACQUIRED), time, 0, numbers, 3, s->walk_variance);
    }
    FTL_(drift_reset)(s);
    s->sc_reacquisitions += 1;
    s->sc_last_reacquired = time;
    s->sc_last_update = time;
    s->sc_announced = 0;
    s->sc_n_previous = 0;
    s->sc_hold_n = s->sc_hold_missed = 0;
    for (j = 0; j < 6; ++j) { s->sc_hold_z[j] = 0.0; }
    for (j = 0; j < 3; ++j) { s->sc_hold_dir[j] = 0.0; }
    s->sc_hold_start = s->sc_hold_last = time;
}
