"""A point in a 2-D U-shaped maze, for pictures of learned rewards (the RILe paper's maze figure).

Any script uses it unchanged, from the repository root, as `--env-id benchmarks.maze_env:UMaze-v0`:
gymnasium imports this module inside `gym.make` (which registers the env), and the scripts live at the
root, so `benchmarks` is importable from their sys.path.

    #####
    #S..#     S: start (top left), G: goal (bottom left); the wall between them makes the U,
    ###.#     so the way from S to G goes right, down and back left (6 cells)
    #G..#
    #####

Observation: the position (x, y) in cell units, y up; the cell of column i and row j (from the bottom) is
[i, i + 1) x [j, j + 1). Action (dx, dy) in [-1, 1]^2 moves the point by STEP * action; a move into a wall
slides along it (the blocked coordinate stays), so no position is ever inside a wall. No termination:
an episode ends at the time limit (100 steps; the shortest way takes 30), so the imitators' absorbing
states never appear and the reward of staying at the goal is learned like any other.
The env reward, for logs and CPR only (no imitator learns from it), is minus the distance left to the
goal: the shortest number of cells from the point's cell to the goal's cell (breadth-first search), plus
the straight distance from the point to its cell's centre.
"""

from collections import deque

import gymnasium as gym
import numpy as np

MAZE = ("#####",
        "#S..#",
        "###.#",
        "#G..#",
        "#####")
STEP = 0.2  # cells per step at full action
MAX_STEPS = 100
START_NOISE = 0.1  # the start is the S cell's centre plus uniform noise of this half-width


def free_cells(maze=MAZE) -> set:
    """The (column, row-from-bottom) of every cell that is not a wall."""
    rows = len(maze)
    return {(i, rows - 1 - r) for r, line in enumerate(maze) for i, ch in enumerate(line) if ch != "#"}


def find_cell(char: str, maze=MAZE) -> tuple:
    rows = len(maze)
    return next((i, rows - 1 - r) for r, line in enumerate(maze) for i, ch in enumerate(line) if ch == char)


def cell_of(pos) -> tuple:
    return int(np.floor(pos[0])), int(np.floor(pos[1]))


def centre(cell) -> np.ndarray:
    return np.array([cell[0] + 0.5, cell[1] + 0.5], dtype=np.float64)


def bfs(start: tuple, maze=MAZE) -> dict:
    """{cell: previous cell} of a breadth-first search over free cells from `start` (4-neighbours)."""
    free, previous, queue = free_cells(maze), {start: None}, deque([start])
    while queue:
        cell = queue.popleft()
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            nxt = (cell[0] + di, cell[1] + dj)
            if nxt in free and nxt not in previous:
                previous[nxt] = cell
                queue.append(nxt)
    return previous


def cell_distances(goal: tuple, maze=MAZE) -> dict:
    """{cell: number of cell moves to `goal`} for every free cell."""
    previous, dist = bfs(goal, maze), {}
    for cell in previous:
        n, c = 0, cell
        while previous[c] is not None:
            n, c = n + 1, previous[c]
        dist[cell] = n
    return dist


def shortest_path(start: tuple, goal: tuple, maze=MAZE) -> list:
    """The cells of a shortest way from `start` to `goal`, both included."""
    previous = bfs(goal, maze)  # searched from the goal, so following `previous` from start walks towards it
    path = [start]
    while path[-1] != goal:
        path.append(previous[path[-1]])
    return path


class UMaze(gym.Env):
    metadata = {"render_modes": []}

    def __init__(self, render_mode=None):
        self.free, self.start, self.goal = free_cells(), find_cell("S"), find_cell("G")
        self.distances = cell_distances(self.goal)
        width, height = len(MAZE[0]), len(MAZE)
        self.observation_space = gym.spaces.Box(np.zeros(2, np.float32), np.array([width, height], np.float32))
        self.action_space = gym.spaces.Box(-np.ones(2, np.float32), np.ones(2, np.float32))
        self.pos = centre(self.start)

    def distance_to_goal(self, pos) -> float:
        cell = cell_of(pos)
        return self.distances[cell] + float(np.linalg.norm(np.asarray(pos, dtype=np.float64) - centre(cell)))

    def is_free(self, pos) -> bool:
        return cell_of(pos) in self.free

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.pos = centre(self.start) + self.np_random.uniform(-START_NOISE, START_NOISE, 2)
        return self.pos.astype(np.float32), {}

    def step(self, action):
        move = STEP * np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        target = self.pos + move
        if not self.is_free(target):  # slide along the wall: keep whichever single coordinate's move is free
            only_x, only_y = self.pos + [move[0], 0.0], self.pos + [0.0, move[1]]
            target = only_x if self.is_free(only_x) else only_y if self.is_free(only_y) else self.pos
        self.pos = target
        return self.pos.astype(np.float32), -self.distance_to_goal(self.pos), False, False, {}


if "UMaze-v0" not in gym.registry:
    gym.register(id="UMaze-v0", entry_point=UMaze, max_episode_steps=MAX_STEPS)
