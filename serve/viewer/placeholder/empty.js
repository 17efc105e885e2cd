// Embedded as /three/three.core.js when the installed three.js has no
// three.core.js (before r171 three.module.js was a single file).
export {};
