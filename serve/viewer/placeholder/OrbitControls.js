// Embedded in place of three.js's OrbitControls when node_modules/three was
// missing at configure time (see placeholder/three.js).
export const OrbitControls = null;
