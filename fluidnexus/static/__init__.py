"""The static scene layer (backdrop, floor, obstacles as Gaussians that do not move) fitted to the views' clean
plates, and the obstacles it shows (docs/static-layer.md)."""
from .layer import (STATIC_FILE, StaticConfig, StaticLayer, fit_static, inside_volume, load_static, render_static,
                    save_static)
from .obstacles import FinderConfig, FoundObstacle, find_obstacles, fit_sphere, merge_with_declared, refine_balls

__all__ = ["STATIC_FILE", "StaticConfig", "StaticLayer", "fit_static", "inside_volume", "load_static", "render_static",
           "save_static", "FinderConfig", "FoundObstacle", "find_obstacles", "fit_sphere", "merge_with_declared",
           "refine_balls"]
