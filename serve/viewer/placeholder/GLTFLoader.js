// Embedded in place of three.js's GLTFLoader when node_modules/three was
// missing at configure time, or has none: the viewer then draws the avatar
// plain, from GET /api/avatar (see placeholder/three.js).
export const GLTFLoader = null;
