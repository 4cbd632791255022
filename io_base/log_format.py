"""Log lines as text (the default) or as JSON lines for a log collector (``--log-format json``).

One JSON object per line: ``time`` (ISO 8601, UTC), ``level``, ``logger``, ``message``, then every
extra field passed with ``log.info(..., extra={...})`` and, on an exception, ``exc_info``.
The service logs one line per state change, never one per cycle, so either format stays small.
"""

from __future__ import annotations

import json
import logging
from datetime import UTC, datetime

TEXT_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
# what every LogRecord carries; anything else on a record came in through ``extra``
_STANDARD = set(vars(logging.makeLogRecord({}))) | {"message", "asctime", "taskName"}


class JsonFormatter(logging.Formatter):
    """A `logging.Formatter` that writes each record as one JSON object on one line."""

    def format(self, record: logging.LogRecord) -> str:
        out = {"time": datetime.fromtimestamp(record.created, UTC).isoformat(timespec="milliseconds"),
               "level": record.levelname, "logger": record.name, "message": record.getMessage()}
        out.update({k: v for k, v in vars(record).items() if k not in _STANDARD and k not in out})
        if record.exc_info:
            out["exc_info"] = self.formatException(record.exc_info)
        return json.dumps(out, default=str, ensure_ascii=False)


FORMATTERS = {"text": lambda: logging.Formatter(TEXT_FORMAT), "json": JsonFormatter}


def current_format() -> str:
    """The format the root logger writes in ("json" or "text"), for a child process to log alike."""
    return "json" if any(isinstance(h.formatter, JsonFormatter) for h in logging.getLogger().handlers) else "text"


def configure_logging(level: str | int = "INFO", fmt: str = "text") -> None:
    """The root logger writes to stderr at ``level`` in format ``fmt`` ("text" or "json")."""
    handler = logging.StreamHandler()
    handler.setFormatter(FORMATTERS[fmt]())
    logging.basicConfig(level=level, handlers=[handler], force=True)
