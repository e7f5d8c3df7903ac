"""A monitor pass's timeline, recorded while it runs and replayed in ``bomc view`` (issue 19).

* :mod:`~bomc_bt.timeline.format` -- the file (``sessions/<n>/timeline.jsonl``): how it is
  appended crash-safely and read back;
* :mod:`~bomc_bt.timeline.recorder` -- the pass's ``on_tick`` hook that writes it.
"""

from bomc_bt.timeline.format import FILE_NAME, Timeline, TimelineWriter, read_timeline, timeline_path
from bomc_bt.timeline.recorder import TimelineRecorder

__all__ = ["FILE_NAME", "Timeline", "TimelineRecorder", "TimelineWriter", "read_timeline", "timeline_path"]
