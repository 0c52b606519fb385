#!/usr/bin/env python3
"""Independent brute force of docs/world.md on exp3, for the exp3 values in worlds/EXPECTED.md.

Shares no code with fulcrum. States are tuples (x, y, mode, inventory, door, boulder);
the state space is a BFS over all 7 actions; E^h is computed by propagating the sets of
reachable projections (the same recursion as fulcrum's engine, written independently,
with Python sets instead of bitsets).

    python3 exp3_bruteforce.py             # docs/world.md: 52051 states, 14849 normal
    python3 exp3_bruteforce.py --horizon 10
        # the matrix at one horizon for every state and row: tool selection's matrix
        # (the world's horizon where the tool is not held, 10 for exp3)
    python3 exp3_bruteforce.py --walk-onto-boulder
        # reproduces the numbers first published in an earlier worlds/EXPECTED.md
        # (35174 / 10048 states): there, an agent moving into an open doorway enters it
        # even when a boulder stands in it, instead of pushing the boulder on.
"""
import math
import sys
from collections import deque

MAP = ["#############",
       "#.....#.....#",
       "#.k...#..>..#",
       "#.....+0....#",
       "#@....#.....#",
       "#..a..#.....#",
       "#############"]
TOOLS = {"k": 0, "a": 1}  # key = tool 0, axe = tool 1
BUG = "--walk-onto-boulder" in sys.argv
ONE_H = int(sys.argv[sys.argv.index("--horizon") + 1]) if "--horizon" in sys.argv else None
CLOSED, OPEN, DESTROYED = 0, 1, 2
DIRS = [(0, -1), (1, 0), (0, 1), (-1, 0)]  # N E S W
tool_at = {(x, y): TOOLS[c] for y, r in enumerate(MAP) for x, c in enumerate(r) if c in TOOLS}
find = lambda g: next((x, y) for y, r in enumerate(MAP) for x, c in enumerate(r) if c == g)
DOOR, BOULDER0, AGENT0 = find("+"), find("0"), find("@")


def rock(x, y):
    return MAP[y][x] == "#"


def step(s, a):
    x, y, mode, inv, door, boulder = s
    if mode == 0:  # normal
        if a < 4:
            dx, dy = DIRS[a]
            t = (x + dx, y + dy)
            if rock(*t) or (t == DOOR and door == CLOSED):
                return s
            if BUG and t == DOOR and door == OPEN:
                return (t[0], t[1], 0, inv, door, boulder)
            if boulder == t:
                b = (t[0] + dx, t[1] + dy)
                lying = b in tool_at and not inv >> tool_at[b] & 1
                if rock(*b) or (b == DOOR and door == CLOSED) or lying:
                    return s
                boulder = b
            if t in tool_at:
                inv |= 1 << tool_at[t]
            return (t[0], t[1], 0, inv, door, boulder)
        if a == 4 and inv:
            return (x, y, 1, inv, door, boulder)
        return s
    if mode == 1:  # choosing a tool
        k = a - 5
        if k >= 0 and inv >> k & 1:
            return (x, y, 2 + k, inv, door, boulder)
        return (x, y, 0, inv, door, boulder)
    k = mode - 2  # choosing a direction for tool k
    if a < 4:
        dx, dy = DIRS[a]
        t = (x + dx, y + dy)
        if t == DOOR:
            if k == 0 and door == CLOSED:
                door = OPEN
            elif k == 0 and door == OPEN and boulder != DOOR:
                door = CLOSED
            elif k == 1 and door == CLOSED:
                door = DESTROYED
        elif k == 1 and boulder == t:
            pass  # the axe has no rule for boulders
    return (x, y, 0, inv, door, boulder)


start = (AGENT0[0], AGENT0[1], 0, 0, CLOSED, BOULDER0)
index = {start: 0}
queue = deque([start])
while queue:
    s = queue.popleft()
    for a in range(7):
        n = step(s, a)
        if n not in index:
            index[n] = len(index)
            queue.append(n)
states = list(index)
succ = [[index[step(s, a)] for a in range(7)] for s in states]
normal = [i for i, s in enumerate(states) if s[2] == 0]
print(f"states {len(states)} normal {len(normal)}")


def matrix_entry(tool, proj, hu=10, he=5):
    acts = [0, 1, 2, 3, 4, 5 + tool]
    sets = [{proj(s)} for s in states]
    by_h = {0: sets}
    for h in range(1, max(hu, he) + 1):
        sets = [set().union(*(sets[succ[i][a]] for a in acts)) for i in range(len(states))]
        by_h[h] = sets
    total = sum(math.log2(len(by_h[he if states[i][3] >> tool & 1 else hu][i])) for i in normal)
    return total / len(normal)


columns = [("door", lambda s: s[4]), ("boulder", lambda s: s[5]), ("door+boulder", lambda s: (s[4], s[5]))]
for tool, name in [(0, "key"), (1, "axe")]:
    hz = (ONE_H, ONE_H) if ONE_H else (10, 5)
    print(name, " ".join(f"{c}={matrix_entry(tool, p, *hz)!r}" for c, p in columns))
