/* Which vest segment a rig's joint moves, from the joint's name (issue 17:
 * a skinned glTF avatar's own weights drive the orientation drive).
 *
 * A joint named X turns the bone from X to its child, so each name maps to
 * the segment of that bone. Recognised, case-insensitively, after any
 * "prefix:" (mixamorig:) and with the side taken from left/right, l_/r_,
 * _l/_r, .l/.r or a Poser-style lowercase l/r before a capital (lShldr):
 *   pelvis  hips, pelvis, root, bip01
 *   chest   spine*, chest, upperchest, torso, abdomen
 *   head    neck*, head*, jaw, eye*
 *   shoulder  collar, clavicle; shoulder where the rig also has a collar
 *             is SMPL's upper arm, else Mixamo's / Biovision's clavicle
 *   upperarm  arm, upperarm, shldr (Poser), shoulder (SMPL)
 *   forearm   forearm, lowerarm, elbow
 *   hand      hand, wrist, palm, and the fingers (thumb, index, middle,
 *             ring, pinky, little, finger)
 *   thigh     upleg, upperleg, thigh, hip (with a side: SMPL)
 *   shin      leg, lowerleg, shin, calf, knee
 *   foot      foot, toe*, ankle, ball
 * Anything else moves no segment (-1): its weight goes to the segments the
 * vertex has besides. */
#include "mim_vest_kinematics.h"

#include <ctype.h>
#include <string.h>

enum { NONE, LEFT, RIGHT };

typedef struct {
    const char *base; /* the name without side, lowercase letters and digits only */
    int prefix;       /* match base as a prefix (spine2, toe_end...) rather than whole */
    int segment;      /* for the left side, or unsided; the right is the next id */
    int sided;        /* the segment has a side */
} rule_t;

#define L(s) MIM_VEST_L_##s
static const rule_t rules[] = {
    {"hips", 0, MIM_VEST_PELVIS, 0},   {"pelvis", 0, MIM_VEST_PELVIS, 0}, {"root", 0, MIM_VEST_PELVIS, 0},
    {"bip01", 0, MIM_VEST_PELVIS, 0},  {"spine", 1, MIM_VEST_CHEST, 0},   {"upperchest", 0, MIM_VEST_CHEST, 0},
    {"chest", 0, MIM_VEST_CHEST, 0},   {"torso", 0, MIM_VEST_CHEST, 0},   {"abdomen", 1, MIM_VEST_CHEST, 0},
    {"neck", 1, MIM_VEST_HEAD, 0},     {"head", 1, MIM_VEST_HEAD, 0},     {"jaw", 0, MIM_VEST_HEAD, 0},
    {"eye", 1, MIM_VEST_HEAD, 0},      {"collar", 0, L(SHOULDER), 1},     {"clavicle", 0, L(SHOULDER), 1},
    {"arm", 0, L(UPPERARM), 1},        {"upperarm", 0, L(UPPERARM), 1},   {"shldr", 0, L(UPPERARM), 1},
    {"forearm", 0, L(FOREARM), 1},     {"lowerarm", 0, L(FOREARM), 1},    {"elbow", 0, L(FOREARM), 1},
    {"hand", 1, L(HAND), 1},           {"wrist", 0, L(HAND), 1},          {"palm", 0, L(HAND), 1},
    {"thumb", 1, L(HAND), 1},          {"index", 1, L(HAND), 1},          {"middle", 1, L(HAND), 1},
    {"ring", 1, L(HAND), 1},           {"pinky", 1, L(HAND), 1},          {"little", 1, L(HAND), 1},
    {"finger", 1, L(HAND), 1},         {"upleg", 0, L(THIGH), 1},         {"upperleg", 0, L(THIGH), 1},
    {"thigh", 0, L(THIGH), 1},         {"hip", 0, L(THIGH), 1},           {"leg", 0, L(SHIN), 1},
    {"lowerleg", 0, L(SHIN), 1},       {"shin", 0, L(SHIN), 1},           {"calf", 0, L(SHIN), 1},
    {"knee", 0, L(SHIN), 1},           {"foot", 1, L(FOOT), 1},           {"toe", 1, L(FOOT), 1},
    {"ankle", 0, L(FOOT), 1},          {"ball", 0, L(FOOT), 1},
};
#undef L

/* Tokens that name the rig, not the bone (mixamorig_Hips, Bip01 L Hand, DEF-thigh.L) */
static const char *const rig_words[] = {"mixamorig", "bip01", "bip001", "bip", "def", "org", "mch", "jbip", "j", "c"};

/* name -> side and base (lowercase letters and digits; side and rig words removed) */
static int split(const char *name, char *base, size_t cap)
{
    const char *colon = strrchr(name, ':');
    if (colon) name = colon + 1;
    int side = NONE;
    /* Poser: lShldr, rForeArm */
    if ((name[0] == 'l' || name[0] == 'r') && isupper((unsigned char)name[1]))
        side = name[0] == 'l' ? LEFT : RIGHT, name++;
    char low[128];
    size_t n = 0;
    for (; *name && n + 1 < sizeof low; name++) low[n++] = (char)tolower((unsigned char)*name);
    low[n] = 0;
    char *at;
    if (side == NONE && (at = strstr(low, "left"))) side = LEFT, memset(at, ' ', 4);
    if (side == NONE && (at = strstr(low, "right"))) side = RIGHT, memset(at, ' ', 5);
    /* tokens between separators: a lone l or r is a side, rig words go */
    char tok[64][32];
    int nt = 0;
    for (size_t i = 0; i < n && nt < 64;) {
        while (i < n && !isalnum((unsigned char)low[i])) i++;
        size_t k = 0;
        while (i < n && isalnum((unsigned char)low[i])) {
            if (k + 1 < sizeof tok[0]) tok[nt][k++] = low[i];
            i++;
        }
        if (k) tok[nt][k] = 0, nt++;
    }
    size_t b = 0;
    base[0] = 0;
    for (int t = 0; t < nt; t++) {
        if (side == NONE && (!strcmp(tok[t], "l") || !strcmp(tok[t], "r"))) {
            side = tok[t][0] == 'l' ? LEFT : RIGHT;
            continue;
        }
        int rig = 0;
        for (size_t w = 0; w < sizeof rig_words / sizeof *rig_words && nt > 1; w++)
            rig |= !strcmp(tok[t], rig_words[w]);
        for (const char *c = tok[t]; !rig && *c && b + 1 < cap; c++) base[b++] = *c;
        base[b] = 0;
    }
    return side;
}

static int match(const rule_t *r, const char *base)
{
    size_t len = strlen(r->base);
    if (strncmp(base, r->base, len)) return 0;
    if (r->prefix) return 1;
    /* whole word, but a trailing number (LeftArm1, spine2) is a part of the same bone */
    for (const char *p = base + len; *p; p++)
        if (!isdigit((unsigned char)*p)) return 0;
    return 1;
}

int mim_vest_segment_of_joint(const char *name, int shoulder_is_upperarm)
{
    if (!name) return -1;
    char base[128];
    int side = split(name, base, sizeof base);
    if (!base[0]) return -1;
    if (!strncmp(base, "shoulder", 8) && side != NONE)
        return (shoulder_is_upperarm ? MIM_VEST_L_UPPERARM : MIM_VEST_L_SHOULDER) + (side == RIGHT);
    for (size_t i = 0; i < sizeof rules / sizeof *rules; i++) {
        const rule_t *r = &rules[i];
        if (!match(r, base)) continue;
        if (!r->sided) return side == NONE ? r->segment : -1;
        if (side == NONE) return -1; /* an arm without a side moves no one segment */
        return r->segment + (side == RIGHT);
    }
    return -1;
}

uint32_t mim_vest_segments_of_joints(const char *const *names, uint32_t n, int *segment)
{
    /* SMPL's "left_shoulder" is the upper arm, because it has a collar; a
     * Mixamo or Biovision rig's "LeftShoulder" is the clavicle */
    int collar = 0;
    for (uint32_t j = 0; j < n; j++) {
        char base[128];
        if (names[j] && split(names[j], base, sizeof base) != NONE && (!strcmp(base, "collar") || !strcmp(base, "clavicle")))
            collar = 1;
    }
    uint32_t seen = 0, mask = 0;
    for (uint32_t j = 0; j < n; j++) {
        segment[j] = mim_vest_segment_of_joint(names[j], collar);
        if (segment[j] >= 0 && !(mask & (1u << segment[j]))) mask |= 1u << segment[j], seen++;
    }
    return seen;
}
