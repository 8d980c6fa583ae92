"""Reading and writing meshes: OBJ, PLY (ASCII and binary), OFF, STL (ASCII and binary), glTF/GLB and OpenUSD.

Formats
-------
The format is chosen from the file extension (case-insensitive) through the
registry :data:`FORMATS` (extension -> :class:`MeshFormat`, as in meshio), or
given explicitly with ``format=``.

========  ==========================================  =====================
ext       read                                        write
========  ==========================================  =====================
``.obj``  ``v`` and ``f`` lines (see below)           ``v`` / ``f`` lines
``.ply``  ASCII, binary little- and big-endian        binary little-endian
                                                      (``binary=False``:
                                                      ASCII)
``.off``  ``OFF`` and ``[ST][C][N]OFF`` (ASCII)       ``OFF``
``.stl``  binary and ASCII (a triangle soup)          binary (``binary=False``:
                                                      ASCII)
``.gltf`` glTF 2.0 / GLB (``gltf`` extra)             the input's document with
``.glb``                                              new positions, or a new one
``.usd``  OpenUSD text and crate (``usd`` extra)      the input's stage with
``.usda``                                             new points, or a new one
``.usdc``
========  ==========================================  =====================

Modules :mod:`~shapeflow.io.gltf` and :mod:`~shapeflow.io.usd` say what each keeps.

Every reader keeps the face structure exactly as written: faces are never
triangulated, face order and corner order are kept, triangles, quads and
n-gons may be interleaved in any order, and every vertex is kept in file order
(unreferenced ones included).  Writers print floats with Python's shortest
round-trip ``repr``, so text round trips are bit-exact; binary PLY stores
float64 coordinates for a mesh from elsewhere and a PLY file's own types when
it is written back (:mod:`shapeflow.io.ply_write`).

Vertex attributes (e.g. the ``"weight"`` attribute) are kept by PLY: each is
a vertex property of the same name in its type (a multi-column one a
property per column).  OBJ and OFF have no place for them: :func:`save` names
what it drops in a :class:`~shapeflow.errors.DataLossWarning`.  Weights can
also travel in side files (``.npy`` or ``.txt``, one number a line) with
:func:`load_weights` and :func:`save_weights`.

Files that refer to other files (glTF buffers and images, USD sublayers,
references, payloads, clips and asset paths): ``load(path,
external_files=False)`` refuses them by name, for files from elsewhere;
with the default ``True`` they are read, USD composing only layers inside
the file's own folder (:mod:`shapeflow.io.usd_layers`).

OBJ details: ``v x y z [w]`` and ``v x y z r g b [a]`` (x y z are used);
``f`` (and the old ``fo``) with ``a``, ``a/b``, ``a//c`` and ``a/b/c`` corners
and negative (relative) indices; ``#`` comments, blank lines and backslash line
continuations; what :mod:`shapeflow.io.obj` keeps (``vt vn o g s usemtl mtllib``,
``l p`` and OpenSubdiv's ``t``) comes back on writing, and every other tag is
counted and named in a warning.  A file without any ``v`` line
is an error.  OFF details: ``#`` comments, the counts on the header line or the
next, ``k i1 .. ik [colour]`` faces, extra per-vertex values (colours,
normals, texture coordinates) ignored; binary OFF and 4D/nD OFF are not
supported.  ASCII PLY is read one element per line.

Errors
------
Anything wrong with a file raises :class:`~shapeflow.errors.MeshError` whose
message starts with the file name, then where: ``line N`` for text formats,
the element for binary PLY (``face 17``).  A missing or unreadable file is a
MeshError too (the OSError, e.g. FileNotFoundError, is named in the message
and chained as ``__cause__``), and so is any other failure of a reader or
its library (out of memory, nested too deeply, pxr's errors), chained to it.

Saving is atomic: the data go to a temporary file in the target directory,
which is flushed, fsync'ed and renamed onto the target; on any error the
temporary file is removed and an existing target is left untouched.

Parsing is vectorised: the text is tokenised with numpy, tokens are grouped
by line, and numbers are converted in bulk (90k vertices / 180k faces load in
about 0.2 s).  Binary PLY lists of mixed sizes need one light Python loop over
the records to find their boundaries; uniform lists (all triangles, all
quads) are read as strided arrays.
"""


from .atomic import atomic_write, output_target
from .obj import read_obj, write_obj
from .off import read_off, write_off
from .ply import read_ply
from .ply_write import write_ply
from .registry import FORMATS, MeshFormat, load, register_format, save
from .stl import read_stl, write_stl
from .weights import WEIGHT_EXTENSIONS, load_weights, save_weights


def _read_gltf(data, name, *, external_files=True):   # pygltflib is imported on first use
    from .gltf import read_gltf

    return read_gltf(data, name, external_files=external_files)


def _write_gltf(f, mesh, *, binary=None):
    from .gltf import write_gltf

    write_gltf(f, mesh, binary=binary)


def _write_glb(f, mesh, *, binary=None):
    from .gltf import write_glb

    write_glb(f, mesh, binary=binary)


def _read_usd(data, name, *, external_files=True):   # usd-core is imported on first use
    from .usd import read_usd

    return read_usd(data, name, external_files=external_files)


def _write_usda(f, mesh, *, binary=None):
    from .usd import write_usd

    write_usd(f, mesh, binary=binary, ext=".usda")


def _write_usdc(f, mesh, *, binary=None):
    from .usd import write_usd

    write_usd(f, mesh, binary=True, ext=".usdc")



__all__ = [
    "load", "save", "load_weights", "save_weights", "atomic_write", "output_target",
    "MeshFormat", "FORMATS", "register_format", "WEIGHT_EXTENSIONS",
]

register_format(MeshFormat("OBJ", (".obj",), read_obj, write_obj))
register_format(MeshFormat("OFF", (".off",), read_off, write_off))
register_format(MeshFormat("PLY", (".ply",), read_ply, write_ply, attributes=True, binary=True))
register_format(MeshFormat("STL", (".stl",), read_stl, write_stl, binary=True))
register_format(MeshFormat("glTF", (".gltf",), _read_gltf, _write_gltf, attributes=True, binary=True, external=True))
register_format(MeshFormat("GLB", (".glb",), _read_gltf, _write_glb, attributes=True, binary=True, external=True))
register_format(MeshFormat("USDA", (".usda",), _read_usd, _write_usda, attributes=True, binary=True, external=True))
register_format(MeshFormat("USD", (".usd", ".usdc"), _read_usd, _write_usdc, attributes=True, binary=True,
                           external=True))
