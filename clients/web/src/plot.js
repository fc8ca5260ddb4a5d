// Line plots with uPlot (bundled; nothing is loaded from elsewhere).
import uPlot from 'uplot';
import 'uplot/dist/uPlot.min.css';

const COLORS = ['#1f5fbf', '#c0392b', '#1e8449', '#8e44ad', '#b9770e'];

function widthOf(container) {
  return Math.max(280, Math.floor(container.clientWidth || 600) - 8);
}

/// A plot in `container`: series [{label, color}] over data [[x...], [y1...], ...].
/// options: {title, xLabel, yLabel, height, time (x is unix seconds), points}.
export function makePlot(container, series, data, options = {}) {
  const opts = {
    title: options.title,
    width: widthOf(container),
    height: options.height || 220,
    scales: { x: { time: !!options.time } },
    axes: [
      { label: options.xLabel, stroke: '#222' },
      { label: options.yLabel, stroke: '#222' },
    ],
    legend: { live: false },
    cursor: { drag: { x: false, y: false } },
    series: [
      { label: options.xLabel || 'x' },
      ...series.map((s, i) => ({
        label: s.label,
        stroke: s.color || COLORS[i % COLORS.length],
        width: 2,
        dash: s.dash,
        points: { show: !!options.points, size: 7 },
        spanGaps: true,
      })),
    ],
  };
  const figure = document.createElement('figure');
  figure.className = 'plot';
  if (options.id) figure.dataset.plot = options.id;
  container.appendChild(figure);
  const chart = new uPlot(opts, data, figure);
  figure.setAttribute('role', 'img');
  figure.setAttribute('aria-label', `${options.title || 'plot'}: ${series.map((s) => s.label).join(', ')} against ${options.xLabel || 'x'}`);
  const observer = new ResizeObserver(() => {
    const w = widthOf(container);
    if (Math.abs(w - chart.width) > 4) chart.setSize({ width: w, height: chart.height });
  });
  observer.observe(container);
  chart.disconnect = () => {
    observer.disconnect();
    chart.destroy();
  };
  return chart;
}

/// Joins curves with different x grids onto one sorted x axis (nulls
/// where a curve has no point), for overlaying two parameter sets.
export function joinCurves(curves) {
  const xs = [...new Set(curves.flatMap((c) => c.x))].sort((a, b) => a - b);
  const columns = curves.map((c) => {
    const map = new Map(c.x.map((x, i) => [x, c.y[i]]));
    return xs.map((x) => (map.has(x) ? map.get(x) : null));
  });
  return [xs, ...columns];
}
