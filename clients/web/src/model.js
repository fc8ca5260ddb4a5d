// Curves of a parameter set (docs/MODEL.md), for plotting only: the server
// owns the model; this reads its JSON.

/// Impulse response of the contraction dynamics H_n(s) = a^n/(s+a)^n
/// (unit area): h_n(t) = a^n t^(n-1) e^(-a t) / (n-1)!, peak at (n-1)/a
/// (Eqs. 4.1–4.4, §4.1). Returns {t_s, h_per_s} over 0..duration.
export function twitch(pole_per_s, order, duration_s, points = 400) {
  let factorial = 1;
  for (let k = 2; k < order; k++) factorial *= k;
  const t_s = [];
  const h = [];
  for (let i = 0; i < points; i++) {
    const t = (duration_s * i) / (points - 1);
    t_s.push(t);
    h.push((Math.pow(pole_per_s, order) * Math.pow(t, order - 1) * Math.exp(-pole_per_s * t)) / factorial);
  }
  return { t_s, h_per_s: h };
}

/// Twitch peak time (n-1)/a in s.
export function twitchPeak_s(pole_per_s, order) {
  return (order - 1) / pole_per_s;
}

/// IRC threshold: the stimulation at which the recruitment R(u) first
/// reaches 2 % of full recruitment (linear between breakpoints, as the PWL
/// IRC itself, §3). A level rather than "last zero" because a fitted IRC's
/// breakpoints need not hold an exact zero just below threshold.
export const THRESHOLD_LEVEL = 0.02;
export function ircThreshold_ma(irc) {
  if (!irc || !irc.stim_ma || !irc.stim_ma.length) return NaN;
  const u = irc.stim_ma;
  const r = irc.activation;
  if (r[0] >= THRESHOLD_LEVEL) return u[0];
  for (let i = 1; i < u.length; i++) {
    if (r[i] >= THRESHOLD_LEVEL) {
      return u[i - 1] + ((THRESHOLD_LEVEL - r[i - 1]) * (u[i] - u[i - 1])) / (r[i] - r[i - 1]);
    }
  }
  return NaN;
}

/// The curves present in a parameter set's "parameters" object, each as
/// {id, title, x, y, xLabel, yLabel}; absent parts are skipped.
export function parameterCurves(p) {
  const curves = [];
  if (p.irc) {
    curves.push({ id: 'irc', title: 'Isometric recruitment curve', x: p.irc.stim_ma, y: p.irc.activation,
      xLabel: 'stimulation (mA)', yLabel: 'activation (0–1)' });
  }
  if (p.contraction) {
    const { pole_per_s, order } = p.contraction;
    const tw = twitch(pole_per_s, order, Math.max(0.3, (6 * order) / pole_per_s));
    curves.push({ id: 'twitch', title: `Twitch (order ${order}, pole ${pole_per_s.toFixed(1)} /s)`,
      x: tw.t_s, y: tw.h_per_s, xLabel: 'time (s)', yLabel: 'h(t) (1/s)' });
  }
  const passive = p.passive || {};
  if (passive.torque_angle) {
    curves.push({ id: 'passive-angle', title: 'Passive torque–angle', x: passive.torque_angle.angle_deg,
      y: passive.torque_angle.torque_nm, xLabel: 'knee angle (deg)', yLabel: 'torque (N·m)' });
  }
  if (passive.torque_velocity) {
    curves.push({ id: 'passive-velocity', title: 'Passive torque–velocity', x: passive.torque_velocity.velocity_deg_s,
      y: passive.torque_velocity.torque_nm, xLabel: 'velocity (deg/s)', yLabel: 'torque (N·m)' });
  }
  const active = p.active || {};
  if (active.torque_angle && active.torque_angle.angle_deg) {
    curves.push({ id: 'active-angle', title: 'Active torque–angle (gain)', x: active.torque_angle.angle_deg,
      y: active.torque_angle.gain, xLabel: 'knee angle (deg)', yLabel: 'gain (1 at 90°)' });
  }
  if (active.torque_velocity && active.torque_velocity.velocity_deg_s) {
    curves.push({ id: 'active-velocity', title: 'Active torque–velocity (gain)', x: active.torque_velocity.velocity_deg_s,
      y: active.torque_velocity.gain, xLabel: 'velocity (deg/s)', yLabel: 'gain (1 at 0 deg/s)' });
  }
  return curves;
}

/// Scalar values of a parameter set for tables and history plots.
export function parameterScalars(set) {
  const p = set.parameters || {};
  return {
    torque_scale_nm: p.active ? p.active.torque_scale_nm : NaN,
    inertia_kgm2: p.passive ? p.passive.inertia_kgm2 : NaN,
    pole_per_s: p.contraction ? p.contraction.pole_per_s : NaN,
    order: p.contraction ? p.contraction.order : NaN,
    twitch_peak_s: p.contraction ? twitchPeak_s(p.contraction.pole_per_s, p.contraction.order) : NaN,
    threshold_ma: ircThreshold_ma(p.irc),
  };
}

export const SCALAR_LABELS = {
  torque_scale_nm: 'τ_scale (N·m)',
  inertia_kgm2: 'inertia J (kg·m²)',
  pole_per_s: 'pole a (1/s)',
  order: 'order n',
  twitch_peak_s: 'twitch peak (s)',
  threshold_ma: 'Recruitment threshold of the model, 2 % recruited (mA)',
};
