// Embedded in place of three.js when node_modules/three was missing when the
// build was configured (serve/CMakeLists.txt); viewer.js shows this message.
export const MIMIC_PLACEHOLDER = 'three.js was not installed at build time (npm ci)';
