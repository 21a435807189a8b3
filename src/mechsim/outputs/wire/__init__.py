"""Wire encoding: messages as the CDR bytes DDS carries, for the nodes and the bag writer alike.

One encoder, generated per type from the type's definition (the ``ros2msg`` text a bag's
schema carries: the ``.msg`` text with its dependencies), serves both one message
(:func:`encode`, :func:`cdr_bytes`) and a chunk of samples given as columns
(:class:`Layout`: the bytes of a prototype message, traced by the same encoder, with the numbers
and stamps of each sample written in). Padding bytes are zero, so equal messages have equal
bytes. One module per job: :mod:`.definitions` (``.msg`` texts, schema text, fields, hash,
class), :mod:`.encoder` (the generated encoder), :mod:`.rows` (chunks as rows).
"""

from mechsim.outputs.wire.definitions import (
    SEPARATOR,
    TIME_TYPE,
    Field,
    full_name,
    message_class,
    message_definition,
    parse_definition,
    schema,
    split_type,
    type_description_hash,
    type_of,
    typestore_with,
)
from mechsim.outputs.wire.encoder import HEADER, cdr_bytes, compile_encoder, encode, encoder
from mechsim.outputs.wire.rows import Block, Layout, time_rows

__all__ = [
    "HEADER", "SEPARATOR", "TIME_TYPE", "Block", "Field", "Layout", "cdr_bytes",
    "compile_encoder", "encode", "encoder", "full_name", "message_class", "message_definition",
    "parse_definition", "schema", "split_type", "time_rows", "type_description_hash",
    "type_of", "typestore_with",
]
