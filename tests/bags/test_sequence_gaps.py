"""Messages a recorder never got, counted from the publishers' sequence numbers."""
from raspv_bags.sequence_gaps import SequenceGaps


def test_holes_in_one_publishers_numbers_are_counted():
    g = SequenceGaps()
    assert [g.seen("/a", n, 0.0) for n in (1, 2, 3, 7, 8, 10)] == [0, 0, 0, 3, 0, 1]
    assert g.lost == {"/a": 4} and g.total == 4


def test_two_publishers_and_a_restart_are_streams_not_holes():
    g = SequenceGaps()
    for a, b in zip(range(100, 110), range(1, 11)):            # two publishers, interleaved
        g.seen("/tf", a, 0.0)
        g.seen("/tf", b, 0.0)
    g.seen("/tf", 1, 1.0)                                       # a third (restarted) publisher
    g.seen("/tf", 2, 1.0)
    assert g.total == 0
    g.seen("/tf", 112, 2.0)                                     # the first one lost two
    assert g.lost == {"/tf": 2}


def test_unnumbered_messages_count_nothing():
    g = SequenceGaps()
    assert [g.seen("/x", 0, 0.0) for _ in range(3)] == [0, 0, 0] and g.total == 0
