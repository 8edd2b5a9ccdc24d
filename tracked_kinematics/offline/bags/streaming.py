"""
The one message loop: the encoder messages to their decoder, the others to a second decoder.

:func:`read_streams` serves every reader of the sub-package: the second stream is the ground truth
for :func:`.reader.read_bag`, the commands for :func:`.reader.read_drive_bag`, both for
:func:`.reader.read_evaluation_bag`, the references for
:func:`.reference_reader.read_reference_bag`.
"""

from __future__ import annotations

from .joint_states import JointStates
from .opening import Progress, topic_connections
from .side_streams import SideStream


def _encoder_stream(reader, path, encoders, ref_ns):
    """Return the collector of the encoder messages and the bag connections it reads."""
    decoder = encoders.decoder()
    enc = (SideStream(encoders, path, ref_ns) if decoder.per_side
           else JointStates(encoders, path, ref_ns, reader.is2))
    return enc, [c for topic in encoders.topics()
                 for c in topic_connections(reader, path, topic, decoder.message_types,
                                            'encoders')]


def read_streams(reader, path, encoders, kind, source, progress):
    """
    Stream the encoder messages and those of one other stream: the one message loop.

    Parameters
    ----------
    reader : AnyReader
        The open bag.
    path : Path
        Its path, for the messages.
    encoders : EncoderSource
        Where the encoders are.
    kind : type
        Decoder of the other stream, made as ``kind(source, path, reader.start_time)``; it
        gives the bag connections it reads (checked) by ``connections(reader)`` and takes
        each message by ``add(connection, message, receive_ns)``.
    source
        What the other stream is (a :class:`GroundTruthSource`, the setpoint topics).
    progress : bool
        Show a progress bar on stderr.

    Returns
    -------
    tuple
        The encoder decoder and the other decoder, fed with every message.

    """
    ref_ns = reader.start_time
    enc, enc_conns = _encoder_stream(reader, path, encoders, ref_ns)
    other = kind(source, path, ref_ns)
    other_conns = other.connections(reader)
    other_ids = {id(c) for c in other_conns}
    conns = enc_conns + [c for c in other_conns if c not in enc_conns]
    bar = Progress(sum(c.msgcount for c in conns), path.name, progress)
    try:
        for conn, receive_ns, raw in reader.messages(connections=conns):
            if id(conn) in other_ids:
                other.add(conn, reader.deserialize(raw, conn.msgtype), receive_ns)
            else:
                enc.feed(reader, conn, receive_ns, raw)
            bar.step()
    finally:
        bar.close()
    return enc, other
