"""The registry of task factories, tagged like dm_control's suites."""

from dm_control.utils import containers

SUITE = containers.TaggedTasks()
"""Task name -> factory returning a task; tags: benchmarking, sparse, follow."""
