"""
The one message loop: the encoder messages to their decoder, the others to theirs.

:func:`read_streams` is the single pass over a bag of :func:`.reader.read_recording`: every
stream asked for (encoders, ground truth, IMU, GNSS, commands) is decoded from the same loop.
"""

from __future__ import annotations

from .joint_states import JointStates
from .opening import Progress, topic_connections
from .side_streams import SideStream


def encoder_stream(reader, path, encoders, ref_ns):
    """Return the collector of the encoder messages and the bag connections it reads."""
    decoder = encoders.decoder()
    enc = (SideStream(encoders, path, ref_ns) if decoder.per_side
           else JointStates(encoders, path, ref_ns, reader.is2))
    return enc, [c for topic in encoders.topics()
                 for c in topic_connections(reader, path, topic, decoder.message_types,
                                            'encoders')]


def read_streams(reader, path, enc, enc_conns, decoders, progress):
    """
    Stream the messages of the encoders and of every other decoder: the one message loop.

    Parameters
    ----------
    reader : AnyReader
        The open bag.
    path : Path
        Its path, for the progress bar.
    enc, enc_conns
        The encoder collector and its connections (:func:`encoder_stream`).
    decoders : sequence
        Decoders of the other streams: each gives the bag connections it reads (checked) by
        ``connections(reader)``, asked in order, and takes each message by
        ``add(connection, message, receive_ns)``; a topic two of them read goes to both.
    progress : bool
        Show a progress bar on stderr.

    """
    targets = {}
    for decoder in decoders:
        for conn in decoder.connections(reader):
            targets.setdefault(id(conn), (conn, []))[1].append(decoder)
    enc_ids = {id(c) for c in enc_conns}
    conns = enc_conns + [c for c, _ in targets.values() if id(c) not in enc_ids]
    bar = Progress(sum(c.msgcount for c in conns), path.name, progress)
    try:
        for conn, receive_ns, raw in reader.messages(connections=conns):
            if id(conn) in enc_ids:
                enc.feed(reader, conn, receive_ns, raw)
            if id(conn) in targets:
                msg = reader.deserialize(raw, conn.msgtype)
                for decoder in targets[id(conn)][1]:
                    decoder.add(conn, msg, receive_ns)
            bar.step()
    finally:
        bar.close()
