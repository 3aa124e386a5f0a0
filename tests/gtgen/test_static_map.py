import numpy as np
from shapely.geometry import box

from gtgen.static_map import static_map_update
from networks.classes import SemanticClass
from networks.mesh import flat_polygon, merge, prism


def test_static_map_keeps_every_classed_triangle_with_its_vertices():
    mesh = merge(
        [
            flat_polygon(box(0, 0, 10, 10), 0.0, SemanticClass.ROAD),
            prism(box(20, 0, 30, 8), 0.0, 12.0, SemanticClass.BUILDING),
        ]
    )
    update = static_map_update(mesh, 1_500_000_000)
    (entity,) = update.entities
    assert entity.frame_id == "map" and entity.timestamp.seconds == 1 and entity.timestamp.nanos == 500_000_000
    assert sum(len(t.indices) for t in entity.triangles) == 3 * mesh.num_triangles
    for prim in entity.triangles:
        pts = np.array([[p.x, p.y, p.z] for p in prim.points])
        tri = pts[np.array(prim.indices).reshape(-1, 3)]
        assert tri.shape[1:] == (3, 3)
    building = max(entity.triangles, key=lambda t: max(p.z for p in t.points))
    assert max(p.z for p in building.points) == 12.0
