"""`cancel` ends a periodic task even when one of its awaits drops the cancel."""

from __future__ import annotations

import asyncio
import sys

import pytest

from io_base.deadlines import cancel


def _periodic_loop_awaiting_replies():
    """A loop shaped like the Modbus client's: await a reply with ``wait_for``, then the next one.
    ``replies`` hands each awaited future to the test, which answers it."""
    replies: asyncio.Queue = asyncio.Queue()
    rounds = []

    async def run():
        while True:
            fut = asyncio.get_running_loop().create_future()
            await replies.put(fut)
            rounds.append(await asyncio.wait_for(fut, 2.0))   # unanswered: TimeoutError ends the task

    return run, replies, rounds


def test_a_cancel_that_wait_for_drops_is_sent_again():
    async def main():
        run, replies, rounds = _periodic_loop_awaiting_replies()
        task = asyncio.create_task(run())
        fut = await replies.get()
        fut.set_result(1)
        await cancel(task)                # its first cancel reaches the task in the reply's step
        return task, rounds

    task, rounds = asyncio.run(main())
    assert task.cancelled()
    if sys.version_info < (3, 12):
        assert rounds == [1]              # wait_for returned the reply, dropped the cancel, and the loop went on


def test_a_plain_periodic_task_is_cancelled_once():
    async def main():
        async def run():
            while True:
                await asyncio.sleep(0.001)

        task = asyncio.create_task(run())
        await asyncio.sleep(0)
        await asyncio.wait_for(cancel(task), 10.0)
        return task

    assert asyncio.run(main()).cancelled()


def test_an_exception_the_task_ended_with_is_raised():
    async def main():
        async def run():
            raise OSError("the PLC went away")

        task = asyncio.create_task(run())
        await asyncio.sleep(0)
        await cancel(task)

    with pytest.raises(OSError, match="the PLC went away"):
        asyncio.run(main())


def test_no_task_is_nothing_to_cancel():
    asyncio.run(cancel(None))
