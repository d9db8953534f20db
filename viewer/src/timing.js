// Frame timing shared by the viewer's page and the three.js peer page (stbs bench
// --viewer): the same loop, so that both are measured alike.

export function median(xs) {
  const s = [...xs].sort((a, b) => a - b), m = s.length >> 1;
  return s.length % 2 ? s[m] : 0.5 * (s[m - 1] + s[m]);
}

/** The median milliseconds of `count` calls of `frame()` (pose upload and drawing),
 *  each followed by a 1-pixel readPixels on `gl`, which waits for the GPU. */
export function timeFrames(gl, count, frame) {
  count = Math.max(1, Math.floor(count));
  const pixel = new Uint8Array(4), times = [];
  for (let k = 0; k < count; k++) {
    const t0 = performance.now();
    frame();
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
    times.push(performance.now() - t0);
  }
  return median(times);
}
