"""Built-in label sets, class lookup by name and synonym, and the ClassNames message."""
import numpy as np
import pytest

from raspv_perception.class_table import ClassTable, canonical
from raspv_perception.label_sets import ADE20K_150, COCO_STUFF_171


def test_label_sets_have_the_datasets_sizes_and_order():
    ade = ClassTable.from_label_set("ade20k")
    coco = ClassTable.from_label_set("COCO-Stuff")
    assert len(ADE20K_150) == len(ade) == 150 and len(COCO_STUFF_171) == len(coco) == 171
    # ids the benchmarks' reference tables give (objectInfo150: person is 13th, 1-based)
    assert ade.names[0] == "wall" and ade.id_of("person") == 12 and ade.names[-1] == "flag"
    assert coco.id_of("person") == 0 and coco.names[80] == "banner" and coco.names[-1] == "wood"
    assert len(set(ade.names)) == 150 and len(set(coco.names)) == 171


@pytest.mark.parametrize("asked, ade, coco", [
    ("person", "person", "person"), ("bin", "ashcan", None), ("trash can", "ashcan", None),
    ("laptop", "computer", "laptop"), ("couch", "sofa", "couch"), ("TV", "television receiver", "tv"),
    ("swivel_chair", "swivel chair", None),
])
def test_names_resolve_through_synonyms_and_aliases(asked, ade, coco):
    for table, want in ((ClassTable.from_label_set("ade20k"), ade), (ClassTable.from_label_set("coco_stuff"), coco)):
        ids, unknown = table.ids_for([asked])
        if want is None:
            assert unknown == [asked]
        else:
            assert [table.names[i] for i in ids] == [want] and not unknown


def test_an_exact_name_wins_over_a_synonym():
    ade = ClassTable.from_label_set("ade20k")
    assert [ade.names[i] for i in ade.ids_for(["screen"])[0]] == ["screen"]      # not screen door / blind
    assert canonical("dustbin") == "ashcan"


def test_world_classes_carry_ade20k_synonyms():
    world = ClassTable.for_world(["none", "floor", "wall", "bin", "person", "laptop"])
    assert world.ids_for(["trash can"])[0].tolist() == [3]
    assert world.ids_for(["computer", "people"])[0].tolist() == [4, 5]
    assert tuple(world.colors[0]) == (0, 0, 0) and len({tuple(c) for c in world.colors}) == 6


def test_unknown_label_set_names_the_known_ones():
    with pytest.raises(KeyError, match="ade20k, coco_stuff, person"):
        ClassTable.from_label_set("cityscapes")


def test_class_names_message_round_trip():
    from std_msgs.msg import Header

    from raspv_perception.segmentation_msg import classes_from_msg, classes_to_msg
    table = ClassTable.from_label_set("ade20k")
    msg = classes_to_msg(table, Header(), "onnx", "/models/segformer.onnx")
    back = classes_from_msg(msg)
    assert back.names == table.names and back.synonyms == table.synonyms and back.label_set == "ade20k"
    assert np.array_equal(back.colors, table.colors)
    assert back.ids_for(["bin"])[0].tolist() == [138]
