// Unit tests (node:test) of the web client's plotting math (clients/web/src/model.js)
// against closed forms: the twitch h_n(t) = a^n t^(n-1) e^(-at)/(n-1)! of
// H_n(s) = a^n/(s+a)^n (Eqs. 4.1–4.4) and the IRC threshold interpolation.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { ircThreshold_ma, parameterCurves, parameterScalars, twitch, twitchPeak_s } from '../../clients/web/src/model.js';

const close = (a, b, tol, what) => assert.ok(Math.abs(a - b) <= tol, `${what}: ${a} vs ${b} (tol ${tol})`);

test('twitch: unit area, peak at (n-1)/a with the closed-form height', () => {
  for (const [a, n] of [[25, 2], [25.8, 3], [12, 3]]) {
    const { t_s, h_per_s } = twitch(a, n, 40 / a, 20001);
    let area = 0;
    for (let i = 1; i < t_s.length; i++) area += 0.5 * (h_per_s[i] + h_per_s[i - 1]) * (t_s[i] - t_s[i - 1]);
    close(area, 1, 1e-6, `area a=${a} n=${n}`);
    const iPeak = h_per_s.indexOf(Math.max(...h_per_s));
    close(t_s[iPeak], twitchPeak_s(a, n), 40 / a / 20000, `peak time a=${a} n=${n}`);
    const tp = (n - 1) / a;
    const fact = n === 3 ? 2 : 1;
    close(h_per_s[iPeak], (a ** n * tp ** (n - 1) * Math.exp(-a * tp)) / fact, 1e-6 * a, `peak height a=${a} n=${n}`);
  }
});

test('IRC threshold: where R first reaches 2 %, linear between breakpoints', () => {
  close(ircThreshold_ma({ stim_ma: [0, 10, 20, 30], activation: [0, 0, 0.04, 1] }), 15, 1e-12, 'mid-segment');
  close(ircThreshold_ma({ stim_ma: [0, 15, 45], activation: [0, 0.01, 1] }), 15 + (0.01 / 0.99) * 30, 1e-12, 'after a small step');
  close(ircThreshold_ma({ stim_ma: [5, 10], activation: [0.5, 1] }), 5, 0, 'already above');
  assert.ok(Number.isNaN(ircThreshold_ma({ stim_ma: [0, 10], activation: [0, 0.01] })), 'never reached');
  assert.ok(Number.isNaN(ircThreshold_ma(undefined)), 'absent');
});

test('curves and scalars of a parameter set, absent parts skipped', () => {
  const set = { parameters: {
    irc: { stim_ma: [0, 20, 40], activation: [0, 0, 1] },
    contraction: { order: 2, pole_per_s: 20 },
    passive: { inertia_kgm2: 0.4, torque_angle: { angle_deg: [30, 90], torque_nm: [-5, 0] } },
    active: { torque_scale_nm: 40 },
  } };
  assert.deepEqual(parameterCurves(set.parameters).map((c) => c.id), ['irc', 'twitch', 'passive-angle']);
  const s = parameterScalars(set);
  assert.equal(s.torque_scale_nm, 40);
  assert.equal(s.inertia_kgm2, 0.4);
  close(s.twitch_peak_s, 0.05, 1e-15, 'peak');
  close(s.threshold_ma, 20.4, 1e-12, 'threshold');
});
