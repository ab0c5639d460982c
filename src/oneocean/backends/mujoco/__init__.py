"""The scene backend: MuJoCo scenes that run the tasks through the same scenario, judge and accounting."""
