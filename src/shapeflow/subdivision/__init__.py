"""Catmull–Clark and simple (linear) subdivision as sparse matrices.

One subdivision step maps the ``n`` old vertices to ``n + E + F`` new ones:

* the old vertices first (same indices),
* then one *edge point* per edge,
* then one *face point* per face (in face order),

and every face of size ``s`` becomes ``s`` quads
``[v_c, edge_point(c -> next), face_point, edge_point(prev -> c)]``,
corner after corner, face after face.  The map is linear, so each level is a
sparse matrix ``S`` (new × old) built once from the topology and applied to
positions and to every per-vertex attribute (``S @ X``); an animated cage then
costs one sparse product per frame.

Rules (those of OpenSubdiv, which Blender's Subdivision Surface modifier uses,
with ``use_limit_surface=False``; ``use_creases`` is ``creases=``, below):

* face point: centroid of the face;
* edge point: ``(a + b)/4 + (f0 + f1)/4`` for a smooth edge (two consistently
  oriented faces), the midpoint ``(a + b)/2`` for a *sharp* edge;
* vertex point, by rule:

  - *smooth* (fewer than two sharp edges): ``(k-2)/k v + 1/k² Σ neighbours
    + 1/k² Σ face points``, ``k`` = number of incident edges;
  - *crease* (exactly two sharp edges): ``3/4 v + 1/8 (a + b)`` with ``a``,
    ``b`` the other ends of the two sharp edges: the cubic B-spline curve rule
    along boundaries;
  - *corner* (a sharp vertex, or more than two sharp edges): the vertex stays.

Sharpness, as OpenSubdiv sets it on the input mesh (the *base level*):

* boundary edges (one face) and non-manifold edges (three or more faces, or two
  faces traversing the edge in the same direction) are infinitely sharp;
* non-manifold vertices (incident to a non-manifold edge, or whose faces form
  more than one edge-connected fan, e.g. two cones touching at a tip) are
  infinitely sharp, i.e. they stay put — except a vertex on an *interior
  non-manifold crease* (exactly two non-manifold edges, no boundary edge and
  more faces than edges), which follows the crease rule along those edges;
* with ``boundary="keep-corners"`` (Blender's ``PRESERVE_CORNERS``, OpenSubdiv's
  ``VTX_BOUNDARY_EDGE_AND_CORNER``) a vertex with exactly one face and two
  edges is infinitely sharp too; with ``boundary="smooth"`` (Blender's ``ALL``,
  ``VTX_BOUNDARY_EDGE_ONLY``) it follows the crease rule like any boundary
  vertex.
* So a boundary vertex with more than two boundary edges (several boundary
  loops touching) is a corner and stays put.

These rules were compared with Blender 5.0.1 (``bpy``) on a bowtie, two closed
fans touching at a vertex, a fin of three faces on one edge, a box with an
inner wall, a quad wound the wrong way and two squares touching at a corner:
the same points at levels 1 to 3.

On refined levels sharpness is inherited, not re-derived: the two halves of a
sharp edge are sharp, the new edges inside a face are smooth, old vertices keep
their sharpness and new vertices have none.

Semi-sharp creases (``creases=(edges, values)``, Blender's c in [0, 1], sharpness
10·c², 10 and more infinite; :mod:`~shapeflow.subdivision.creases`): an edge point
is min(s, 1) of the way from the smooth point to the midpoint, the halves of an
edge have sharpness s − 1 (0 from s <= 1 on), and a vertex whose rule one level
down differs from its rule here is blended, w × this level's point + (1 − w) ×
the next level's, w the mean sharpness of its edges that become smooth (at most
1): OpenSubdiv's uniform creasing, which Blender sets.  Compared with Blender
5.0.1 on 13 cases (tests/data/blender_creases): 1.4e-7 of the diagonal.

``scheme="simple"`` keeps the same connectivity with edge midpoints, face
centroids and the old vertices unmoved (Blender's ``SIMPLE``).  Vertex weights
in Blender follow that linear rule in both schemes (``weights_rule="linear"``).

Vertex order: Blender builds the mesh's edges from the face list
(``BKE_mesh_calc_edges``): edges in order of first use walking the faces'
corners (edge ``prev -> corner``), split over hash maps by the parity bits of
the lower vertex index when the mesh has 1000 faces or more and Blender runs on
several threads.  With ``edge_order="blender"`` edge points are numbered like
that, so one level reproduces the vertex and face order of Blender's modifier
exactly (for meshes whose edges Blender computed from the faces);
``blender_threads`` picks the number of hash maps Blender used.  Several levels
are applied one after the other here, while Blender evaluates a grid per face;
the points and faces are the same but listed in a different order.
"""

from .api import subdivide, subdivision_matrix
from .rules import BOUNDARY_RULES, BYTES_PER_FACE, SCHEMES, WEIGHT_RULES

__all__ = ["subdivide", "subdivision_matrix", "SCHEMES", "BOUNDARY_RULES", "WEIGHT_RULES", "BYTES_PER_FACE"]
