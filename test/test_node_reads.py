"""The nodes' read and feedback helpers: pull-model subscriptions and the feedback rate limit."""
from std_msgs.msg import Int32

from conftest import wait_for
from skillgen_ros.nodes.feedback import FeedbackThrottle
from skillgen_ros.nodes.latest import LatestMessage, close_all


def test_feedback_throttle_limits_rate_but_always_sends_the_final_step():
    now = [100.0]
    fb = FeedbackThrottle(hz=20.0, clock=lambda: now[0])  # a stepped clock, not a sleep
    assert fb.due()  # the first step always goes out
    now[0] += 0.04
    assert not fb.due()  # a step 40 ms later does not (20 Hz: 50 ms)
    assert fb.due(final=True)  # the last step always does
    now[0] += 0.06
    assert fb.due()
    every = FeedbackThrottle(hz=0.0)  # 0: no limit
    assert all(every.due() for _ in range(5))


def test_latest_message_takes_the_newest_on_demand(ros_node):
    pub = ros_node.create_publisher(Int32, "numbers", 10)
    reader = LatestMessage(ros_node, Int32, "numbers")
    try:
        assert wait_for(lambda: pub.get_subscription_count() > 0, 10)
        assert reader.latest(timeout=0.2) is None  # nothing published yet
        for i in (1, 2, 3):
            pub.publish(Int32(data=i))
            assert wait_for(lambda: (m := reader.latest()) is not None and m.data == i, 5)  # observed, in order
        assert wait_for(lambda: (m := reader.latest()) is not None and m.data == 3, 5)  # depth 1: the newest
        msg, count = reader.snapshot()
        assert msg.data == 3
        assert reader.wait_newer(count, 0.3) is None  # nothing newer: times out
        pub.publish(Int32(data=4))
        newer = reader.wait_newer(count, 5.0)
        assert newer is not None and newer.data == 4 and reader.count > count
    finally:
        reader.destroy()


def test_latest_message_never_returns_the_previous_read_while_a_newer_one_waits(ros_node):
    """Every read takes the newest sample. Fast DDS hands a sample to a reader of the same participant
    inside publish(), so it is waiting when the read comes. Through rclpy's executor alone every
    other latest(0) returned the message of the read before (its handler wakes the next spin_once on
    the executor's own guard condition): perception then posed Coffee Prep's drawer shut while it was open."""
    pub = ros_node.create_publisher(Int32, "numbers_every_read", 10)
    reader = LatestMessage(ros_node, Int32, "numbers_every_read")
    try:
        assert wait_for(lambda: pub.get_subscription_count() > 0, 10)
        pub.publish(Int32(data=0))
        assert reader.wait_for(lambda m: m is not None and m.data == 0, 5.0) is not None
        got = []
        for i in range(1, 21):
            pub.publish(Int32(data=i))
            got.append(reader.latest().data)
        assert got == list(range(1, 21))
        assert reader.count == 21
    finally:
        reader.destroy()


def test_latest_message_follows_its_owners_remaps(ros_node):
    import rclpy

    owner = rclpy.create_node("remapped_owner", namespace="/w1", context=ros_node.context,
                              cli_args=["--ros-args", "-r", "numbers:=counts"])
    pub = ros_node.create_publisher(Int32, "/w1/counts", 10)
    reader = LatestMessage(owner, Int32, "numbers")
    try:
        assert reader.topic == "/w1/counts"
        assert wait_for(lambda: pub.get_subscription_count() > 0, 10)
        pub.publish(Int32(data=7))
        assert wait_for(lambda: (m := reader.latest()) is not None and m.data == 7, 5)
    finally:
        reader.destroy()
        owner.destroy_node()


def test_close_all_shuts_every_open_reader_down_once(ros_node):
    """runtime.run_nodes calls close_all before rclpy.shutdown: a reader's executor left open past
    the context printed an InvalidHandle traceback from Executor.__del__ at exit (a CI failure)."""
    readers = [LatestMessage(ros_node, Int32, f"numbers_{i}") for i in range(2)]
    names = [r._node.get_name() for r in readers]
    assert wait_for(lambda: set(names) <= set(ros_node.get_node_names()), 10)
    close_all()
    assert all(r._exec._sigint_gc is None for r in readers)  # what Executor.__del__ would touch
    assert wait_for(lambda: not set(names) & set(ros_node.get_node_names()), 10)
    close_all()  # nothing left open: a second call is a no-op
    readers[0].destroy()  # and so is destroying a reader already closed
