"""Built-in label sets of semantic-segmentation datasets (no ROS): a model trained on one of
them only needs the set's name in its label file.

- ``ade20k``: the 150 classes of the ADE20K SceneParsing benchmark (Zhou et al., CVPR 2017), in
  the order of its ``objectInfo150`` table (id 0 = "wall"), each with the table's synonyms.
  Models trained with the benchmark's usual "reduce zero label" setting output these ids.
- ``coco_stuff``: the 171 COCO-Stuff classes (Caesar et al., CVPR 2018; 80 things then 91
  stuff) in the contiguous order segmentation toolkits train with (id 0 = "person").
- ``person``: background / person (the shipped selfie-segmentation model).

Names are lower case; synonyms let a user ask for "trash can" and get ADE20K's "ashcan".
"""
from __future__ import annotations

# ADE20K objectInfo150: "name;synonym;synonym…" per class, id = position.
ADE20K_150: tuple[str, ...] = (
    "wall", "building;edifice", "sky", "floor;flooring", "tree", "ceiling", "road;route", "bed", "windowpane;window",
    "grass", "cabinet", "sidewalk;pavement", "person;individual;someone;somebody;mortal;soul", "earth;ground",
    "door;double door", "table", "mountain;mount", "plant;flora;plant life", "curtain;drape;drapery;mantle;pall",
    "chair", "car;auto;automobile;machine;motorcar", "water", "painting;picture", "sofa;couch;lounge", "shelf",
    "house", "sea", "mirror", "rug;carpet;carpeting", "field", "armchair", "seat", "fence;fencing", "desk",
    "rock;stone", "wardrobe;closet;press", "lamp", "bathtub;bathing tub;bath;tub", "railing;rail", "cushion",
    "base;pedestal;stand", "box", "column;pillar", "signboard;sign", "chest of drawers;chest;bureau;dresser",
    "counter", "sand", "sink", "skyscraper", "fireplace;hearth;open fireplace", "refrigerator;icebox",
    "grandstand;covered stand", "path", "stairs;steps", "runway", "case;display case;showcase;vitrine",
    "pool table;billiard table;snooker table", "pillow", "screen door;screen", "stairway;staircase", "river",
    "bridge;span", "bookcase", "blind;screen", "coffee table;cocktail table",
    "toilet;can;commode;crapper;pot;potty;stool;throne", "flower", "book", "hill", "bench", "countertop",
    "stove;kitchen stove;range;kitchen range;cooking stove", "palm;palm tree", "kitchen island",
    "computer;computing machine;computing device;data processor;electronic computer;information processing system",
    "swivel chair", "boat", "bar", "arcade machine", "hovel;hut;hutch;shack;shanty",
    "bus;autobus;coach;charabanc;double-decker;jitney;motorbus;motorcoach;omnibus;passenger vehicle", "towel",
    "light;light source", "truck;motortruck", "tower", "chandelier;pendant;pendent", "awning;sunshade;sunblind",
    "streetlight;street lamp", "booth;cubicle;stall;kiosk",
    "television receiver;television;television set;tv;tv set;idiot box;boob tube;telly;goggle box",
    "airplane;aeroplane;plane", "dirt track", "apparel;wearing apparel;dress;clothes", "pole",
    "land;ground;soil", "bannister;banister;balustrade;balusters;handrail",
    "escalator;moving staircase;moving stairway", "ottoman;pouf;pouffe;puff;hassock", "bottle",
    "buffet;counter;sideboard", "poster;posting;placard;notice;bill;card", "stage", "van", "ship", "fountain",
    "conveyer belt;conveyor belt;conveyer;conveyor;transporter", "canopy",
    "washer;automatic washer;washing machine", "plaything;toy", "swimming pool;swimming bath;natatorium", "stool",
    "barrel;cask", "basket;handbasket", "waterfall;falls", "tent;collapsible shelter", "bag",
    "minibike;motorbike", "cradle", "oven", "ball", "food;solid food", "step;stair", "tank;storage tank",
    "trade name;brand name;brand;marque", "microwave;microwave oven", "pot;flowerpot",
    "animal;animate being;beast;brute;creature;fauna", "bicycle;bike;wheel;cycle", "lake",
    "dishwasher;dish washer;dishwashing machine", "screen;silver screen;projection screen", "blanket;cover",
    "sculpture", "hood;exhaust hood", "sconce", "vase", "traffic light;traffic signal;stoplight", "tray",
    "ashcan;trash can;garbage can;wastebin;ash bin;ash-bin;ashbin;dustbin;trash barrel;trash bin", "fan",
    "pier;wharf;wharfage;dock", "crt screen", "plate", "monitor;monitoring device",
    "bulletin board;notice board", "shower", "radiator", "glass;drinking glass", "clock", "flag",
)

# COCO-Stuff: 80 thing classes, then 91 stuff classes (171), contiguous ids.
COCO_STUFF_171: tuple[str, ...] = (
    "person", "bicycle", "car", "motorcycle", "airplane", "bus", "train", "truck", "boat", "traffic light",
    "fire hydrant", "stop sign", "parking meter", "bench", "bird", "cat", "dog", "horse", "sheep", "cow",
    "elephant", "bear", "zebra", "giraffe", "backpack", "umbrella", "handbag", "tie", "suitcase", "frisbee",
    "skis", "snowboard", "sports ball", "kite", "baseball bat", "baseball glove", "skateboard", "surfboard",
    "tennis racket", "bottle", "wine glass", "cup", "fork", "knife", "spoon", "bowl", "banana", "apple",
    "sandwich", "orange", "broccoli", "carrot", "hot dog", "pizza", "donut", "cake", "chair", "couch",
    "potted plant", "bed", "dining table", "toilet", "tv", "laptop", "mouse", "remote", "keyboard", "cell phone",
    "microwave", "oven", "toaster", "sink", "refrigerator", "book", "clock", "vase", "scissors", "teddy bear",
    "hair drier", "toothbrush",
    "banner", "blanket", "branch", "bridge", "building-other", "bush", "cabinet", "cage", "cardboard", "carpet",
    "ceiling-other", "ceiling-tile", "cloth", "clothes", "clouds", "counter", "cupboard", "curtain", "desk-stuff",
    "dirt", "door-stuff", "fence", "floor-marble", "floor-other", "floor-stone", "floor-tile", "floor-wood",
    "flower", "fog", "food-other", "fruit", "furniture-other", "grass", "gravel", "ground-other", "hill", "house",
    "leaves", "light", "mat", "metal", "mirror-stuff", "moss", "mountain", "mud", "napkin", "net", "paper",
    "pavement", "pillow", "plant-other", "plastic", "platform", "playingfield", "railing", "railroad", "river",
    "road", "rock", "roof", "rug", "salad", "sand", "sea", "shelf", "sky-other", "skyscraper", "snow",
    "solid-other", "stairs", "stone", "straw", "structural-other", "table", "tent", "textile-other", "towel",
    "tree", "vegetable", "wall-brick", "wall-concrete", "wall-other", "wall-panel", "wall-stone", "wall-tile",
    "wall-wood", "water-other", "waterdrops", "window-blind", "window-other", "wood",
)

PERSON: tuple[str, ...] = ("background", "person;people;human;pedestrian")

LABEL_SETS: dict[str, tuple[str, ...]] = {"ade20k": ADE20K_150, "coco_stuff": COCO_STUFF_171, "person": PERSON}

# Everyday names → the ADE20K class that covers them (beyond the table's own synonyms), so one
# request ("bin", "laptop", "people") finds the right class in the world, ADE20K and COCO-Stuff.
ALIASES: dict[str, str] = {
    "bin": "ashcan", "waste bin": "ashcan", "trash": "ashcan", "garbage": "ashcan",
    "laptop": "computer", "notebook computer": "computer", "pc": "computer",
    "people": "person", "human": "person", "pedestrian": "person", "man": "person", "woman": "person",
    "couch": "sofa", "dining table": "table", "desk-stuff": "desk", "door-stuff": "door", "potted plant": "plant",
    "plant-other": "plant", "tv": "television receiver", "staircase": "stairway", "cupboard": "cabinet",
    "window-other": "windowpane", "mirror-stuff": "mirror", "wall-other": "wall", "floor-other": "floor",
    "ceiling-other": "ceiling", "sky-other": "sky", "window-blind": "blind", "carpet": "rug",
}
