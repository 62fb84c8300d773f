"""The warehouse's shared task table: taking a cart is atomic across connections (workers, processes)."""

from __future__ import annotations

import threading
import time
from collections import Counter
from pathlib import Path

from examples.warehouse.behaviour import Cart, TaskTable


def test_concurrent_takers_never_take_the_same_cart(tmp_path: Path) -> None:
    table = TaskTable(tmp_path / "tasks.db")
    carts = [Cart(f"cart{i:03d}", i, (float(i), 0.0), "ABC"[i % 3], (9.0, float(i))) for i in range(120)]
    table.create(carts)
    taken: list[tuple[str, str]] = []
    lock = threading.Lock()
    start = threading.Barrier(8)

    def worker(robot: str) -> None:
        con = table.connect()  # one connection each, as separate processes would have
        start.wait()
        while (cart := table.take(con, robot)) is not None:
            with lock:
                taken.append((cart.id, robot))
            time.sleep(0.002)  # moving the cart, outside the transaction
            table.finish(con, cart, moved=True)
        con.close()

    threads = [threading.Thread(target=worker, args=(f"robot{i}",)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    counts = Counter(cart for cart, _ in taken)
    assert sorted(counts) == [c.id for c in carts] and set(counts.values()) == {1}
    assert len({robot for _, robot in taken}) > 1  # the work was shared
    assert set(table.states().values()) == {"moved"}


def test_a_cart_comes_back_as_it_went_in(tmp_path: Path) -> None:
    table = TaskTable(tmp_path / "tasks.db")
    cart = Cart("cart2", 2, (0.0, 3.0), "A", (8.0, -2.0))
    table.create([cart])
    con = table.connect()
    try:
        assert table.take(con, "rb1_base_a") == cart
        assert table.take(con, "rb1_base_b") is None
        table.finish(con, cart, moved=False, note="door stuck")
    finally:
        con.close()
    assert table.states() == {"cart2": "failed"}
