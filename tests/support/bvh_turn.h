/* A BVH text as another author would have written it with another up axis:
 * every OFFSET, and every channel's axis and value, turned by the quarter or
 * half turn that takes +y to `up`, so that reading it back and standing it
 * up must give the original positions. For the up-axis tests. */
#ifndef MIM_TEST_BVH_TURN_H
#define MIM_TEST_BVH_TURN_H

/* The turn that lays a y-up file down with `up` as its up axis (+x, -x,
 * +z, -z, -y: 1, -1, 3, -3, -2; +y 2 copies): for +z, the file's (x, y, z)
 * is (x, -z, y) of the y-up one (Blender's z-up convention: its y-up
 * export maps (x, y, z) to (x, z, -y)); for +x, (y, -x, z). Returns the
 * malloc'd text (fails the test on text it cannot follow). */
char *bt_turn(const char *bvh, int up);

#endif
