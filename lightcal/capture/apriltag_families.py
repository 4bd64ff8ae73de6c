"""The AprilTag families OpenCV also has (16h5, 25h9, 36h10, 36h11), as published.

Over 500 lines for a reason: it is data (3,000 codes), with no logic to split along.

Data, not code: each family's codes (in id order, as hexadecimal) and its bit layout,
read from AprilRobotics/apriltag's tag family sources (`tag16h5.c`, `tag25h9.c`,
`tag36h10.c`, `tag36h11.c`; BSD 2-clause licence, Copyright (C) 2013-2016 The Regents of
The University of Michigan). `lightcal.capture.apriltag` draws the official tag images from
them.

`FAMILIES[name]` is an `AprilTagFamily`: bit k of a code (the most significant first) is
the module in column `bit_x[k]`, row `bit_y[k]` of the tag's black square (row 0 at the
top as printed, column 0 at the left; the square is `width_at_border` modules wide, its
outermost ring black), white where the bit is 1.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FAMILIES", "AprilTagFamily"]


@dataclass(frozen=True)
class AprilTagFamily:
    """One AprilTag family as published (see the module docstring).

    Attributes:
        name: The family's name, e.g. `"tag36h11"`.
        n_bits: Bits per code (data modules).
        min_hamming: The family's minimum Hamming distance.
        width_at_border: Modules across the black square (data and black border).
        bit_x: (n_bits,) column of each bit in the black square.
        bit_y: (n_bits,) row of each bit in the black square.
        codes_hex: The codes in id order, hexadecimal, separated by spaces.
    """

    name: str
    n_bits: int
    min_hamming: int
    width_at_border: int
    bit_x: tuple[int, ...]
    bit_y: tuple[int, ...]
    codes_hex: str

    @property
    def codes(self) -> tuple[int, ...]:
        """The codes in id order."""
        return tuple(int(code, 16) for code in self.codes_hex.split())


_TAG16H5 = AprilTagFamily(
    name="tag16h5",
    n_bits=16,
    min_hamming=5,
    width_at_border=6,
    bit_x=(1, 2, 3, 2, 4, 4, 4, 3, 4, 3, 2, 3, 1, 1, 1, 2),
    bit_y=(1, 1, 1, 2, 1, 2, 3, 2, 4, 4, 4, 3, 4, 3, 2, 3),
    codes_hex=(
        "27c8 31b6 3859 569c 6c76 7ddb af09 f5a1 fb8b 1cb9 28ca e8dc 1426 5770 9253 b702 063a "
        "8f34 b4c0 51ec e6f0 5fa4 dd43 1aaa e62f 6dbc b6eb de10 154d b57a"
    ),
)

_TAG25H9 = AprilTagFamily(
    name="tag25h9",
    n_bits=25,
    min_hamming=9,
    width_at_border=7,
    bit_x=(1, 2, 3, 4, 2, 3, 5, 5, 5, 5, 4, 4, 5, 4, 3, 2, 4, 3, 1, 1, 1, 1, 2, 2, 3),
    bit_y=(1, 1, 1, 1, 2, 2, 1, 2, 3, 4, 2, 3, 5, 5, 5, 5, 4, 4, 5, 4, 3, 2, 4, 3, 3),
    codes_hex=(
        "156f1f4 1f28cd5 16ce32c 1ea379c 1390f89 034fad0 07dcdb5 119ba95 1ae9daa 0df02aa 082fc15 "
        "0465123 0ceee98 1f17260 14429cd 17248a8 16ad452 09670ad 16f65b2 0b8322b 05d715b 1a1c7e7 "
        "0d7890d 1813522 1c9c611 099e4a4 0855234 17b81c0 0c294bb 089fae3 044df5f 1360159 0ec31e8 "
        "1bcc0f6 0a64f8d"
    ),
)

_TAG36H10 = AprilTagFamily(
    name="tag36h10",
    n_bits=36,
    min_hamming=10,
    width_at_border=8,
    bit_x=(
        1,
        2,
        3,
        4,
        5,
        2,
        3,
        4,
        3,
        6,
        6,
        6,
        6,
        6,
        5,
        5,
        5,
        4,
        6,
        5,
        4,
        3,
        2,
        5,
        4,
        3,
        4,
        1,
        1,
        1,
        1,
        1,
        2,
        2,
        2,
        3,
    ),
    bit_y=(
        1,
        1,
        1,
        1,
        1,
        2,
        2,
        2,
        3,
        1,
        2,
        3,
        4,
        5,
        2,
        3,
        4,
        3,
        6,
        6,
        6,
        6,
        6,
        5,
        5,
        5,
        4,
        6,
        5,
        4,
        3,
        2,
        5,
        4,
        3,
        4,
    ),
    codes_hex=(
        "1a42f9469 21a48c08d 26dfdbc5d 2d19b78fb 31c5557df 3f2b3d349 3e6d4a7a5 43d6dfb6d "
        "5688d2aff 54663b474 67fd759e4 73b196d82 7de71c630 8492722d4 835407afa 893a6fe16 "
        "95668d348 9c20e37a4 a19bb676c ad1355c1b b2ab4ac53 b14f27095 bef6b014d c9ecbadc7 "
        "e1996a6bd edc588fcb f26d9d7a1 035e79c1a 1644f74a8 1bfda85e0 20573db2a 27614bfd6 "
        "2daf26b72 332930a98 3176c5674 3892ad2d0 3fd4d26ac 4b88a1fca 555b6b579 6103880d7 "
        "6045e58fb 6dedf28a3 72766f249 7e4a0c77f 973ba8e61 965fd5285 9d99bd6a9 a221264e6 "
        "a1455fcca a7cb3193e aead44d92 ad50ac954 b2f0bb19c cba043aa2 d73d7f6b4 d6d189310 "
        "f41278885 1c45306af 222b4420b 2d70ceeb1 392cb439f 45d1179ee 57a79d05c 62bc91dd6 "
        "73ca773c0 8b3da6eb0 9c5a521c7 a812a1881 adeab4859 b3402b213 b9171667f f5ac6918c "
        "0549b1cfc 0b2744a58 0ae12ceb4 2f8aaab94 38db1c43b 4be190989 51bef9565 505a8d1c3 "
        "575ce25bf 68ac14eb1 6fd1bca45 854752994 9e96b442a afb308f74 cd9c8ca44 d23c9b28e "
        "d07277423 e8b3a6959 f44bc546f 10e4aa7f3 29971cc68 62d7b0b94 8c22aac77 8b46d70d3 "
        "a43373b0d e2efd2c74 f5f4587e6 01b82bfa0 0642bef7a 1e576f881 2a290cda7 3b1ae80b1 "
        "53b9317e3 5833ac709 5f25d3ff5 648fcef3d 68d6350d6 8064a4da6 92b76e736 9157102b0 "
        "9eef0de60 b098e9306 b63e94718 c1241e99b eab42b39f fca2a422d 007f86a4b 124962550 "
        "1fe977988 300a8b4c4 76c2b21a1 932f76619 9994e9b51 a634fcb8b b6d92c074 bcbf53858 "
        "c0c3a0d7e 01c31a9c3 0d5a694d5 12f2fc41d 5a342598a 6466af138 81eb68f22 98e885eb6 "
        "ab594f405 b19f201a1 d44832643 fdc915802 0ee4f05dc 3043aa2a6 3765d7a9a 5468500ab "
        "59d38dc6b 60b5e288f 9539ba6df 9a93219d2 ad81ab160 abe7d650c beb8dd89e bd5432e10 "
        "09aafb509 14f535a9b 202956e9d 3d64508f8 5babe994e 6d1c1e752 94cb57d7b 9a45c8c11 "
        "a7f4dd4c9 d6ab9426b da6766828 f1608f9bc 16ad49fb6 6da68e61f 6ce0e03bb a0404d752 "
        "e066e102f 2f9d00546 39878a9e4 49521229c 8a70b85a9 96ecdad9d 9b5300ed7 d08e19cd0 "
        "e1dbbf0a6 ef012435c 6ecd2fc10 749a519f4 91b715e4c 90f17dae8 975d0ae16 9ced1f6de "
        "ba3660c0b d1b1c9d9d d77fa492b de0bdcdc7 e2472e389 39ee6b70e 7a8ad48b3 b4ee1682e "
        "bb8a7ec82 07cd0404d 11d68ecc7 46cbd039d 4b634dd1a 63c6d44e0 981a82ea0 a93f25d5f "
        "a8795d9fb b5d3c69a3 f56912854 1f86096b4 1ee865210 24bf5c67c 37a5d0bee 3c2fcd384 "
        "5324bc851 5886a7099 b72fa2c2c fc92eb5b5 422e4a0c6 59b17b310 8e7d2e941 943f50c2d "
        "93db38889 d3c56115c ec3097940 f0c8e4c64 15a1a2b44 31885e859 3c77ec56f 665489b09 "
        "ac8831e70 b0559325e d9d4e401b 1618bca4b 6cd54c849 717d5b003 acb7e0f3d db2c90514 "
        "edb75ab84 2d2d82857 95fb613c6 9c1f187c8 b1521d0f9 f252b178d 3fe0f8640 5ca93c171 "
        "9dad88605 b32a795d4 d0273d2e4 d7034b6d8 21d211a8b 32f7b66d5 97f46e061 a3a80d947 "
        "af24f7511 17760c682 2f17d53f8 5768d8553 5ccac399b b363443b6 86e868835 d1f31c586 "
        "e3c1f8c18 dfb29b8f1 12545997c 3c9b87c9c 650afceda 7cc5d2d4d e97f2c6b4 bcf094d17 "
        "c2b6fd1b3 55b7539e1 6563c3099 6cbcaa475 711ebf8bf beacf0872 152bf7dd3 2d9e666a9 "
        "8aadf624c ae04840c3 b89fceccb 391534881 6d3b626f3 b8cd3f384 56e622ea0 72da9effc "
        "9d9dc3195 9b5bab5bb a2255635f b3d6b2a41 e1e78a0ca 6f166d850 6ed013c3c 974124e7a "
        "b9c237103 12a55c948 6e6e02db3 bb970b4ae cb5e92956 24a8a8519 5e4e6a504 cce402a5b "
        "ead45ac6b b7e065329 2c9b38934 550a5f272 9af15026b c43acbba9 03c4f2ed0 5a6df5a79 "
        "acf8a733e e05408ed3 60787293b 89e95533f dcb673abc e0ea10fda efa4f932e 45e988b2b "
        "5d2c11c5e b84be5c13 50629a003 5e11c1dd3 12111629f 2365f3381 4cf5d41c0 8d957e5b5 "
        "25b88ce2c 41ec563d3 c3884919f 4ffd91f28 d6211be2e 2c6c33e2b 9b062517d 9a605d5d1 "
        "c93615ffb 0587aa508 ae741eba5 4b232ba75 9d68187b1 a253c3b79 bae55c0a6 d0eaa3172 "
        "c0c2dbd49 d1d37d23f e952ecf4f a51239d5e f6e416099 da4923cf8 55cd5bbbf 67fad4a0d "
        "6f802d5ab 4c90df6ab cc0aad0e1 745207f2b b516ad892 8da9ca7d8 ba7517799 b13811fcd "
        "0328436ca 5965ad68f e6b65823f 951a1abf3 95cce7616 ca003fe57 d5ee5d32b 2d6d58f8e "
        "bee25c778 21cac7ed2 7b982415f 237a92d3e 65c2a898a 2a67c67d0 492c37445 e66713585 "
        "adb041611 9b5ed4c88 f2f751a83 05a5db231 8478d5037 5e2954c13 0d8597d1d 537116e24 "
        "7ce063461 a79a20302 b8016f46a ebeb44bdc 206e7cff7 0d2870a69 4e21e723a 6a59590e7 "
        "a522a2e9b c2ec8f44f 03e51273c 56bab7c9b b3a92fa7e f4a993d4b 8b80884b7 8a5339f30 "
        "690c7389d 9f34cb283 cd0febc20 f579a2a82 3ba18373f 68fddad38 7ca529286 df93cd25b "
        "7d18313a9 febd825c0 898d72da2 c2d8c5ade 60b797eea 7281731bd b48a4940a d7e28a20d "
        "06d0aac8e 2f418d6e8 45ce7d55f bb3415aa6 f592d643d 0c556e7e9 dede56c4e 075f63628 "
        "778f69c5b b0add7ab7 d86f0b737 6d3092589 776618a1b ecec99b8c 38a56d5b3 e0cb464d1 "
        "0b9385f3a ba42a64f5 938bb73f3 a7691cb01 86a986dad 447ed963b b6bcab900 a348c9079 "
        "71812b90b be867b1a9 7807672ae f52c97520 05f6dabb7 1321e1472 e44ab0b16 31b1b920f "
        "e7a916c37 ec3a095dd e1cc9b481 46209b37b 47f0aa439 0d7b31bef 52db78a32 ed3b35ea8 "
        "5b1f58572 acf866c7d fa2be6544 774737a28 bcf8fe9b1 fdfc4ac80 a0aef3457 5d93f4f4a "
        "a314ac7fa b52221849 b5d908dac ec20c9ce2 da5563b12 57257c59b ef0e8f782 f9d2b3dc4 "
        "ab8097620 b99a08aca 064fe5b8b 19255e746 aab6d88b0 e011adc1b 3214f657c 093f917b4 "
        "91f0c7859 bcd3a5171 0afd4cb29 8787d5924 24f3a8b55 2ae32d017 67af72a45 8fe87d42a "
        "902c5df3f 2f2500693 868a4733c 5dd4c95d9 97210f5f2 23f0de89f 84ce8a4b5 34eb80e3d "
        "532c70dec 13b90cb54 c3dfe6cb7 8b03d0bad 90bacd3e5 afa0bc824 a38fe08f8 fa758ea36 "
        "fe0862d3c 1ace4f7ed e04bac135 63e99b95a b010d68e1 ce9352b2b 82838db6f d3bf04d59 "
        "c9df5aec3 a4e8aafee 6b1db1459 6ba3217d0 e5c73549c 37c2679df 732d69874 73ce98c9e "
        "4cc0f5c5e 08f1b8c73 ef1b22865 06f5eb759 1476bea11 78ba48850 74ac468d5 8ed2a2869 "
        "a0d4f4fcd 2401bcfac af4852356 e49487115 678ebe495 3afec50b5 ff853144e ca35def53 "
        "87328bda4 d258703b5 71152a781 4dd323e43 4812c5a59 57bd1d082 456266e15 6b9fccad6 "
        "4abe3b07b baf59cfce 56d6932fc fd158446c 363f31ca6 93c9eecce 33930d57f 62c9dcfbb "
        "6f52475c4 950d51d55 95c430b37 7424acdf9 5e59f504f 7abe9fe84 1462e4fb3 5b346387f "
        "adcf80432 dbcf4c50e 213274059 7d0da7a11 d9c5de950 334edcf91 eaadbf8b8 4fd450926 "
        "9a8af56b0 28b062348 86bd1c31d 0d15dd6c2 8cc9d14c6 d0b9038c4 b445f90b9 c3378c977 "
        "197aa5976 f5879d3e2 2ec330e97 4bcab4ba7 185b91b99 9a64ecebf e8b66c585 5e1e848ec "
        "a24ca255b 6a0d7dfc7 770e1711a 7e34402b4 525ceff8c 89a56e0c9 ee1401ffc b13cfa633 "
        "327aa9b9a 77383d86d eb6d7283e 4ba294b54 26c84d5d9 1c2c5adc0 694e6ec3c 0f3064d10 "
        "6b7c9d416 d7d74bd89 e11232372 4d84369e0 f7de40249 b64950611 a0724a19b 688eef9ab "
        "3c7a3a2ea 49cd79585 6c35bff78 456a31970 4205eb8ec 2717c22e3 763d127fb 865548e6f "
        "4f1dcc597 279dcfca4 aad1f2e05 6437570c6 d68b74cd9 ec82e7216 4223b2229 9c12a8582 "
        "c073eb63d 68b779e29 61157ce5f 50f6ebec2 35f4e4b1c f909c56d6 9c4b78474 b8160eb1e "
        "5e3d256f8 21919b529 d4c7b6226 5190049a8 ad869eab6 a10b3759a 917560e43 2c5d651d7 "
        "eb2c8e47c bc131902d 7e883469b 91d991bfe 20c3a7704 2b3b53f8f 8978b2c6a 91138b228 "
        "529f08e2c 979342793 98137dcc3 3a9c6e139 f898abd5e ce2585f36 968312f45 2994a6ec2 "
        "ca6685871 a3af94337 03f628d34 1e9617f6c a34ed1a9c 2c22028b4 fdeb13f3a 02d85e3ac "
        "957491696 ac42bab89 e3753d50f b712a307a 8b7c1c2ca 8893cb8f8 5abc4467f 5f1aa96c0 "
        "b7dcde504 c3cd9ca20 0af48c055 f4e10477b 12b45078c 10af764c6 23d8b32d5 36f1e9c47 "
        "e847bd756 4c3b4e455 64d42e688 cf5218b7a cdc1605e4 6250bba26 be6c4770a 982331a23 "
        "dfd090dca 506bc18d5 109d7375c 680ca4a7e a6e1c91e1 688f44350 ad470ae05 f3ff0a79e "
        "326f26fbe 4105901be 32ed82cd9 09916c638 1d0025ed6 4aeaec114 98af27931 968f79b3b "
        "ed4b906d5 61ae9b2e4 59b82a3f5 550eb833b 17b69fd4b 73d569e02 63dba43f8 f6cb4cb8a "
        "d6258181b e86109784 fa5a660ea 4f9815064 75d8db35d 546f94888 58df2d00a 6a779d19b "
        "ea1b4e76b 14870eef0 55429f855 e86b71b9f d333c2d43 42733ecd4 d16ba12ef 3b69c3d5c "
        "4a5c07666 a84634048 21a2c4b26 573be1892 730bd1d40 eed055d81 7e815e7a6 8ab11c883 "
        "50283e7d2 c8a795b85 47a229dc5 12b9e108c caa2034db a62f9ae47 93979dcfa 5fb8fd985 "
        "25bf32ccb 7ae9a5ee5 b10665d2e ed0c2b0e6 2c72c25fd d74f444d2 9b0db80cb 55c8e43de "
        "d77253912 84cfd9ea0 1615ba8c5 503884d62 fc53328a8 f547a6153 ca97160cf 95e440434 "
        "6fa4c125d a420cfe45 af8147dfb 12e90ddea f14c3cb5e 966579d6a 4447c94d0 32336acea "
        "c75d077df b7e72837e 51d24ed1e 93fb67f5c 85cedc1b2 3ca6c5d2b 32269be93 120ed410c "
        "fe115d3d4 0a045ed79 83e2846de 4e7a34f3b 5078cae37 c831aa1f0 79de6b9b6 8e39b1ad2 "
        "66bdb37a5 4a79f5da7 cd9693b30 0dc69a07a 8649a002f 932887d37 3926b6a74 c5d4f8ff8 "
        "ea290f911 360e344e9 7fa9e8a19 b1d0c16c3 1bbe55ddc 825cdaea9 04f67f00f d3df43a25 "
        "b07b349a2 716a39611 aa0fc66b7 f928fca14 697c299d3 6dea5d945 38cee4ea7 4e67ea7b6 "
        "24deb4062 e4428a670 8fdb1ad13 318ff0e1c 08c148b5d dbf90b839 03ea5b027 42b077ba9 "
        "b528450e0 a1256cbfd 4798a8e57 1fdc0d38f 146329edc fa0f94b03 56c6f0e19 06db661a7 "
        "681addf27 0d1eded30 765c3d6e7 1ba6ae5ad 5e0b49af4 33176fa1c 64ca46a3a 389363b6f "
        "8cc072db9 b25f03d8f 56aa81ab1 2b1c37b54 ac1c3279d 669af74ed 64816db93 254f44a17 "
        "c1f5fc290 ebca3a222 20e75e68b d3bb4dfc2 8d9167a74 b6de37939 f7a9a93d6 9aab08164 "
        "6d186ddfc 04d3e529c a53e2a5c4 d5e40b964 9a1d76463 7ad6a8ecc 30b0c9279 351e5b489 "
        "bba967fe0 ab3d8bf17 16c42b17a 9744fae63 77a3f2d39 83c0190ac 8d016cba0 5eb9f1e35 "
        "6349c2c93 f5a15e641 7a5bc8c86 65b6b9834 b756618a7 d297dc208 3d6cfca2a c26e4a930 "
        "3afd2df57 7f990decd 6665a2f43 345d16f4f 322e392bd 567baa5de 4a6412121 a102338a6 "
        "b130fd768 72a30a317 e4b71cd71 ad4b2ceeb 1da4e11cf d5df39b45 81622faa8 98f38af5c "
        "25397c292 2cfcdb0d7 d24542679 04f04f5f4 254842f2c c6fce4a81 1518648bf 29ead8e85 "
        "dc1435a6b c8ebc91af bcc94c093 8285d6a81 5b5cca263 05279a4fd 8c7dc69a7 963e0b3fc "
        "e38519cb6 e84af68a5 d20ee188d 74fdc8660 56f95f633 f5d2233bf ecb3c9815 c21a3cee6 "
        "1558f2f83 8ea10ea50 7ededa109 4d4c5e25d 130e15fa7 64c873cc7 35a0225a3 d37aefb27 "
        "b441d8903 2339f650b c52d79fa9 a28badc40 e2b99967c 8726656b3 124e07029 8582b1dab "
        "4eb90cbee bff16b8ac a408251fd 4feccced5 edda7bf1c 55a0d37b2 0dd9dc90e a537c9ad8 "
        "8b007aeb4 6e17fbab4 0d03559e3 66fb4aaac d06449a6b 528bb1818 48f0d8bae 834d540b7 "
        "23d5d9ab9 1a13b04d1 bd30cc9af e392c0fb4 fd5d4e8bd cbc646d45 348db96b7 e32e54c5f "
        "62446b63f ea47a2c4d 8d4d99969 d01d6d0d2 1862cef24 ed64fe4ba d48b40fec 30aa27a14 "
        "8b2fcfdce 943824f9a bab9f8d09 3204c129f 823a36283 5a0b07693 437949450 4ad8ca4c5 "
        "ec979f418 e4ed18627 8cd5d978d 5b33248f0 bf5ac9f64 bd427f795 d19d39539 9f4a46c35 "
        "532019548 b0ebce22c b91133fbc 6f1983636 8f898fed7 e642bf2cc a8841dfe9 c6b879b48 "
        "7ad82cc2e 651977fc1 4dcf4f025 c94950e6c 2595c6edd d4490ebe6 4105ad270 903d8c8ef "
        "62531ad0b 1c1fd55b3 d27d4ced8 dc62f305b 1e2557e49 495c28ced 9c279d9db 52aa6cef5 "
        "7ea533ab1 d7d49e37b e8c5c7424 8137f4da1 ae13670b3 0de97bd57 0759a6643 d646248df "
        "f5f13b6a3 d12b2ecad 205cccbb8 fe6a5b5f2 d1995e567 91d0f2174 360e9ebef d304c9653 "
        "7eb43d360 9b24edb22 5aeb87d49 73a745811 e1fd08936 33eeb68a9 6367edc20 36fd414d2 "
        "2e6722e78 6c7a9c15e 2330d46f7 b6bc7a6e8 43eb954aa 05eadcf50 63e43b4ea 0351ca1f1 "
        "8b5682648 c28f03f9a 636bfe005 4ca1054e5 440ed66c9 6e60f6fbc 6d94e25ee adfe9ec25 "
        "f0cb53616 cb19d69aa ff898685e 66ea208d6 5dadebaf0 f3f7afea5 a96739522 39a0ef88e "
        "626acbb6e ce0e42f8d 883ae2d8f 619bd4ce7 be466b665 79e154eae 73e2a0a7a 5ec94e92c "
        "898bc6465 abce956eb 2b21e8995 86364e87d d58212c13 8b8c39e93 0a1546c8b 8abbe32b5 "
        "e8a4a2512 ad5ee178b 69cc1e886 5bc2f8d35 1bbcd0982 1fd969b1a ae9e4251b 9afc001ad "
        "69e9d82f9 92f852ed7 adb6d7fe1 67b91999d fa2600b99 d6735277e f836268ed b7911c708 "
        "13427930e f24a44da1 ed2f760e0 920508584 9f1b07e2b 32c15b482 ffcd64b43 a055b6498 "
        "b2a107a8b 191147253 9c214bb01 8bb616abd 1ef7dea4a 9dd6d225d 95563112c 01e4d0569 "
        "f21a51b18 686d2a5eb 32032674a c3d902590 856c92019 58ebdcd91 df2c7f9ae 89d852225 "
        "862c4110d dc7df8185 c16e1da36 5a6749140 0e94d9865 32ec4b2fe c80777c94 6869a7d57 "
        "8de18dc8e c98cc7379 79a6fa3a2 8b854287d 55bcd493b f3ddb56ec d15ec6405 316f82362 "
        "39676e2a1 4044e831a 8444cf83b 64658814c d7ad48a68 d5eb72583 e11057b5d b7e3cd622 "
        "a6a2f9c78 a5924afe8 40a92e9ba 367a3950f 8dee1ebe9 52b717d05 9a5691e7d d454d2e0f "
        "fd8b299e9 b2b1b84c2 4eacf400b 81eb4687e 5cd851fa7 1c285ea35 8ac9fdc95 1b612a6c3 "
        "94f92a63a 7debaf7c8 8cbcb7d94 e439689ea 0932e63d2 f3f641704 1acb5259e 321ea6e39 "
        "61c65c02f 4282e42f2 1dd4ff338 d91e27631 d93927fce 4d40d6ae7 5bbfd1359 88bd393fe "
        "2535b3fd7 b705488d3 9aa688843 9fa55ccf0 02cf10ca5 8235e2861 2610f1f02 b203fbac1 "
        "e05f02f3c b0d0e50ad 244eee955 4c5beb90d 13343b3c4 21bf9a392 be95ecb69 bc65857e2 "
        "8185173f4 c3f6d059d 35c94e74a f72a083a3 5b36eab8f aa28606bb 447d407bd d47eafc61 "
        "4e4dd872f abd276950 b999bc572 8e0c5cee3 9fd2442d0 bcb568051 b87a1635b b3557c1e5 "
        "ce9b07f46 0b6dfcfd2 28a540e7b bb04666c4 b7baf38c6 c37168124 ca3c9589d 3529b99c0 "
        "e8afab685 bdc566027 3f1ded61b ce9930acd 08aa447db 77a696e73 0eb44d17b c5d9c164d "
        "1f98d7237 56a327041 e9ecd1e58 0c2e0c7f4 abf4a1a5e 9395c523e d014134fa 5fbd62cad "
        "b247b4af6 413f6fb3b 61c6ea7c4 8015ac6a5 0baf0e3dd ba1215e4a b01a9b92e c1516251f "
        "01d0eeda9 cf17f566f 3203947b3 7c92be543 c320f34b8 6b1ff7e93 29d39ef02 eda7b1139 "
        "cca47d853 7ad24144d 7b082f234 a6ec32320 cf89eda25 b64064998 fa2314616 d21789ac2 "
        "d3c8d0f5d 6bac87d8d 1ff1311bd 2a1584b86 b23dc8745 eda5fcd76 a7a9261d0 512745cf6 "
        "2fc13fa8b e733958d3 a057fc27d b4ffd8bbc 2abff4fb6 1d148a214 d3c3c41fb 0cf542a81 "
        "ee518b8db 5d97028fa 0dd153679 d8e1610b5 575122bab 090fec0a7 5aa2ee7de 116ae8273 "
        "16991092e 3ab370aa5 3f0c514e6 340ce20ad d1cbbebb8 aff5b363d 2f31fb255 5b7e53a8a "
        "58d91de7c 6fdf2521f 80d755cb9 cf8c9903b 0ab7ef0c7 3c61bf489 fbfd14815 baa647e90 "
        "daf22defe 1a54cfe57 54d061818 158deb36d a7955893a 409b1960b 21cfed67e b478f7f56 "
        "2ff42f95d 48a06d3ec 170957703 3925ece98 d929cec5b aa5813ee5 9fb913a1e 465854b47 "
        "8ac8a7343 84451853b 49987e033 75cd03c35 cf326e2c1 ed14fdb95 31a390e60 a1959d956 "
        "1985d18b3 0b6b8bb85 dc3fa4c95 3645fcf45 6c2146e60 8bdeaf7d6 5d0d268cf 8df1d5b62 "
        "77506eed4 5bebc26a3 c78584caa 7ee6685bd 0d8af0a56 e3a0db991 625de434d 582318bce "
        "3ebe2bc3c ebd301053 5f579e6d7 e9810d2ae b893145b4 a7e7836d1 679dac13b 8d99e4704 "
        "1c7234de5 f23b8b6db de8a6f02f bd2026bf8 bb3903264 ede8048af 60161ef64 8fc791a5b "
        "6a4546243 bc8187b47 ff2ca8dca 6bf71b837 78b8d1fe8 e738cdd2a 7aa80d490 fd1026293 "
        "c96fe6ad3 83f0f4f7b 75cb39786 b6ef13bdd f6a89f8a5 99a14349e 1ce6c16e5 a7597498f "
        "145206424 013c9c5b3 d25775fc6 72311ca63 936d4cfe7 9ce43a505 663594c01 42d1be7b6 "
        "80b1dc92d 20e8e5b75 0c2337a9e 58ae29f6b 90c553143 5b06da028 9415b2520 5dabcde8b "
        "d3c804332 028d103db 7be4cf210 56f76dd52 3877e1a3b 1f93eb430 0588972ac c76cd7eb1 "
        "852596e61 6fa0ead03 d78be2bb6 56fdd6fd1 e265b0ebd cc715a846 ffb1e87a8 d9893a834 "
        "054c56923 63bbaac88 76a5585d4 607b37e59 ee4d4018b 7ef2d8dc5 c1c2d4285 1e0be0a7b "
        "9fbdac67e dc5c74ca1 8366e2f1c abf1e4843 7b55f4dac 3d6150197 4e034c8db 63df500df "
        "34b89afd5 0a5ddabc7 9ee6ff8ec 3cdd9a682 a8d46f842 5fec25f7d 4216835cf 1624430f9 "
        "18afb5b6c 9ffd34c8e 95d5882ed 2e28d07cf fd9163bc2 a5d0833d8 3ebaf5bfd 89a7a3e54 "
        "85d3f7dd8 8af8d1ba1 a5b4e01b7 9f1accb0a 2fe5fcb31 2c4484bed a124de2ee 51471f700 "
        "14f7195f8 3ab7e9700 4542a74bf 9a01158f7 1f288d502 af0834285 c936df23f 2d38ea826 "
        "b1966249a bc43458d4 11eb6a09c d49d9986c dd9067c0e ce383aa71 0739c5a2f 770f58eaa "
        "a5d87da4d 401b685ac c65512bc1 6999d7387 e23d36997 e30f1d174 16e46fc04 200efa090 "
        "18d86ea94 b75de5761 9e50de39d d7a0a0161 537a63844 e4f4de023 c5b83066f b9a2f9eb6 "
        "82a761d43 7088ad873 5b512f418 a373cf2e4 5937d7c89 cca051304 7a84e3efb 74d80c91b "
        "4ad73e91d 490cea84a 52e4f1987 ec811379e b4f570589 5a6c46e81 ca857bada bb9c86860 "
        "b2632ee04 3f597b324 7df14d546 5978d3925 98498767b 15966a839 6923743ef 52f38b460 "
        "6a2df69ed 84151f66c 1ee304eab a082ae4af 0de4e6afa 8131b4166 af5b7967a 16d942f84 "
        "dab10053e cce886f54 39bc89ef4 a5b7d9067 2fb039e23 06d82231d 03a946dd7 8b719555c "
        "5352ece13 904fb9151 c7d7cc8d1 d20511b70 f2411eeb8 5b4a24ed9 c00fe866f eb118811a "
        "cabf21b14 052e3a95f 506d306f1 22cd662d4 89161da55 7db947827 b70b47976 814e4e0ed "
        "8cb8f07f3 b6979fdc4 b0eebb6b0 5ec980ef2 4b53ccab8 9c80770e3 b7ee43a52 a8ef24d04 "
        "9ec4f67e6 d5f2fb080 efc528d35 db181ccfb 39330efd0 1a7dd101a 4ac3982ec 7037e17dc "
        "366188495 02458d8a7 5f004f923 4fe549703 4d33fc825 016f29207 a5b2b61a0 d9ea2cb3f "
        "09d5e3b9b 4e473ff93 51e981524 68db475ad def9cdca4 44a257b51 50a9ee66a 7b40b799b "
        "4111f2de4 cfcfb6b09 f2412713a 8d799e9dd 534748e45 32f291f51 030363bd3 12906d84d "
        "6bd9344a9 61a5524f1 a94d8e02b 82d03a557 468cdf94a bdd69de40 ea8853fd9 d6caf9343 "
        "01755e839 badf446de fe70eae5a 1f3817ad1 91db0de1a c1fc0df55 b55de01cc 66c5829bd "
        "33cb31ff9 ad671f856 534431aef d30fd939a 826d24c57 d40d5f1b1 58f22448c 83611d663 "
        "f4df3f635 1c1071941 0f870bccb 13a62329e 6d6e094a0 13c44a6a7 129bc445b 59ee90dfd "
        "0e0a5171a 5f92372ba 8638592ef 00d72f3b5 bc7e60a8c ce5895c63 e41b1ca5d e615ea62c "
        "6993e2180 0cc37d82c 26af573f3 1eb95a424 50e5fbc99 fb89b34b2 9571a8d0f 9d1a63a99 "
        "9a033e7e7 d77b20f8c ed2ce19b0 5731543c1 a59b97f53 1b3503950 7cc1f4899 3b5a20f14 "
        "3fb33bf95 24850c92f e3e322563 ba303ab82 5a004a3cb 1bc3a579d bc3dd3ba0 df582df03 "
        "dfd57af2c 3863e1da0 dac52e26f 8eb863556 94d19e451 1d50d8f5f 27d1987de 0aadc2f1e "
        "d55af6b1d 737fe1509 a49e0fe3b 2a49eeaf9 0c946b05c ca43c3583 19f868513 69cbd7558 "
        "5043e7034 616e82885 fd919ba26 b50ca391f c1c578673 d4cb35af7 f82970fb0 2fe746c03 "
        "8a89c5009 6228cb500 27ea5af6b dbce2be47 bd304a07c 436d1ffec e616c764a e50868951 "
        "08cb63318 06a39fbc8 d42cede82 814c745ce d9032244b e20bc0e5a 2ce95450b 15cae0ea8 "
        "4a2ff168f 3c6b4fe2f 1999a6d47 df7755c04 0e2da75e1 cfb8748c2 6472c5913 ca51e4ce0 "
        "34f2ca384 7b305ce7c f3704894a 55945c075 104252729 b16e409ff 3676f5fc8 8b9ba144f "
        "a322964e9 09841268b 8c8912053 db2e4f8d1 62a58cbf4 34a15524c 0e73ea403 38492c5dc "
        "865ab5b6d b638c0fbd 85ce2ca0e e45949e30 0431f7881 4f8626706 f59c896ce 8d4e37dd7 "
        "72e5e016b 19c9570a6 eb0e55828 f3cb02a1b b609ff814 dab87f876 76d547356 b9f95ae4e "
        "63a65e9e3 b6838a991 12b64eb81 c59ced5a6 d715aecdb b4291fe13 06d0d0693 f98794c86 "
        "5c816d4d8 c947590ff 80bb44a94 f59bd80c8 df761d2bc 217a8fb51 93d47240d 761920193 "
        "e4e5eba29 eeca76549 a1bbfc9c4 c711b2477 325b5a666 ce05f41f2 3da9c4cff 120c47b51 "
        "cd32263ae e799e7548 ae372d335 063ddbda3 267fac28c 01fc9d86b 17641543b c72e347da "
        "6ffd0717a 3c30cb70f 0820ea2bd 3e9d4bf2b a3c30b85c f9f0118df e4b9fe4d3 29c0611ae "
        "a8c35fa15 1b9e934ca 480cb9d1b bf800f039 c84dca5d6 7bc72f527 7b9239fae 7d89ef157 "
        "7ac85a437 d16f6d1be edf98b6ff e8686dc27 4859dce4b 041627612 fc09cbd90 fdae828b9 "
        "8e8ab9aac e3c3a5acb df138b3f6 68b6499ce bf229a907 c5565d691 8f8119c05 96751f8e6 "
        "ac2f319d4 dc9a8a43b 23e877e11 6bd59226f 59360ec26 e9afc1dd5 de69624a6 de54a22a7 "
        "ea27ba143 8bcdef6a3 4779f40be 65a1a6cbc f31b71b67 1dee9ec9b a8bbd546b 4d77af897 "
        "53be52417 9ab39f2e2 c7672be23 85bb59414 f77b6f781 aecf29f03 3ea7deeb5 53154616b "
        "f0ad4172e ac97900c4 24af96431 742dcac09 b77612a7c 43f8e0b06 b9af4d04c 5f0c0eeb7 "
        "beed5d839 594bc055f bf3d4ee51 36dc329e7 6292a913d 853afc28d 8f669cd4d 35d67967d "
        "a1ba1cda9 475e70d85 db124355e b7464de4b 210a5d6ec 3f3b26a00 3b654ab0b 5461eabb8 "
        "add3bc40f 0223eae50 d0a8f290d 70ec2982d 0e98ba15a 1bf087c2e 6e98233f2 b06e2c22b "
        "45483b62d 2fadab9ae 112d8a187 c1a9043c6 07abad130 92fd1710e f55801505 f42daa0b3 "
        "63e7b4d45 f976ab37b 59c9833d0 98cbdb021 da67a27ca d0e6edf39 d8fdd70b9 6b86d3b06 "
        "3979ed2b7 46a8a0a6c fba0b5f5f c34a9713d 840e7387c ca04d9f6a 76073e651 e6f2fca96 "
        "daef51fa4 7824e6073 dbbb9e428 64bda5a5d d3944a8be 895b7c247 a8a092b5e 8454ae0f6 "
        "1a3109cc6 411731a19 ee3ccd9e5 865688814 84c59bdd7 bdf4f34e2 192b2633c f7c30ff94 "
        "bbd0187c5 36858be42 7cf38933f b1c48417e 77b63288c 794af1c0e b5afd4a02 92e67eb6b "
        "6253569e5 1405ca65f 4ca61bba3 06fe876e9 c25b98680 0bd52f241 de92bdbc6 7114244f7 "
        "c92109927 11246d25f 878963531 b8f639289 edd1ee2dc 2dd27bd83 5b77fb633 92d244fea "
        "ff29f378b cd74b01df caee75d99 32a7950e7 8ab7143d0 4a396d396 27cc982aa 748ffbcac "
        "7dc1212db 60491f30f 6462a44c5 f693b3934 2c85c32c8 58842e73a 39c5c936a 59da18b06 "
        "b0c4be569 b38429749 14d177c42 b2890755c c316f3c01 97a978118 6e3af9c97 b16bfcf5b "
        "fbdedeaa1 62d2efff3 221e13b03 6f189a8f4 ba3c855cf 4d9b593f1 70bdb83c4 7be402a75 "
        "acbb1dcf6 6d76dd708 4210a8723 e4a9e3182 0b86ea177 589c7c8df 728f649cc 235daf936 "
        "ed5b13b07 9838cc62b 699ea0fb3 533af329d 0486ec47d ea7e7874d ae99ea9c5 37e02d2d5 "
        "b92cf5ea1 e8c6fa527 93ac59f00 a5876d0fb 42664d4ab 672c67c2f a499d1a9b 1c55c99a8 "
        "5d5644f76 149b6cd96 5d19a752a fa5fce591 5380ec50c dea0d752d 1faf5309b e3b7a775e "
        "173d59edb b8e38cca5 1e43cad4e 27dedf623 da72d480f 99434d76f 8e06320e5 12cc5d9b3 "
        "d4ec00d0a 8fa256ec8 2a7755b41 649598f17 048a9ea61 b749bbe4d 59e4c9da2 50395f36c "
        "6b07149d2 4f9406d7f 92febe987 d7bf93ed2 1e66cc0f3 6c48e37c0 3ad8159d5 48f41fbc8 "
        "cd5f40d31 4d9d50e50 377552d44 d6400b5bf 205260a56 c319eaf12 bb3016818 194c9caa5 "
        "3205df053 8dbf64dc8 5cc34b609 7d2367f18 20d6cee2e c9f86c18e e2b1f4620 09c52f03e "
        "07d8b9b31 2b85f049f e0b542614 d0f06b745 df7b0f962 d7b41890f 24baf7927 cc63c5347 "
        "c9dbe3e8e 52b1c7225 73f558c8d 542702b85 578f18fdd a76cf36ef a3cb92407 b7ad6cd05 "
        "6d0f34533 416083d1b 2bdb7fab0 29619e1d2 fe824f4c1 7a5ff22b9 5be7f7ce2 4140ddebe "
        "ec104f338 3c6ea6417 4c68c4841 738550624 95d52ffbe 1211a3407 85c2667c7 d3fcfc70a "
        "62c79fa03 e5a01d1de 21a6f78c0 67a9d08d0 3521d86a9 821858962 0238c9ab4 d377e444e "
        "9b4db4370 326d40d28 cca399d64 29e717061 81c257536 b5398ff6f 6246d505d 52de44206 "
        "d4bfe70a7 1256f3bbf e18dca845 cadc6270e ceecebcf9 30490b131 3499eae73 e407687b5 "
        "0d16a1b5c 0aed4fc7c 977235ace e45bc089c d1c7e8b0f c801f2a62 9bb982feb c2ade21d5 "
        "e664c4cdc b5b1b7d8d 57e319e42 a62708260 4d49e8e90 0cb5f349a 97f8c8487 bf26ecbd1 "
        "6a22fc93f f40123ad5 f2864b84f 52b894393 aeac3e443 64a6e37e9 5ff905511 0f9368ae9 "
        "304c961d1 901e3d5ef 3d9c9e1ea 14af08310 f7d5f48fa 4cc90c712 93eb3c4f2 c64af2ee0 "
        "ee9b0b880 59e9f00c4 f0e385a56 013e3176a 22cefe2bf e8d646da2 fa07e9914 64a342dc3 "
        "029436fde 3f436a788 ebce59d33 d1cc417e5 bdabb3afc 2b075aa91 cf479bc86 1bc69c922 "
        "f70bed102 73fba7412 dad289c99 25fa19a7e a5a248105 59c85904f 587368f7a 6ddf6cd9b "
        "276aaeac2 39793390e ee79121bd 43b22f813 137d42357 67857c8bd 46cf4e741 1d18cd171 "
        "a9806c31f 06605176c 0f592c1ac 7265a10a4 e89d3f153 b2c1d25d5 fc221a68c 21bc5cb0f "
        "7d8865a48 14fb6a9c1 826702ff5 c875eecdd 334906e55 e75f38920 e68cc8585 e21989dad "
        "991c0a54f afc2e4db2 49215ae09 4414dd21c 270102c2b d74d46724 d8ba0e6cf 4924c591c "
        "14a218727 ec649a317 40506e864 4a5fce324 432da3920 be6c87867 96d47ab50 13b26554a "
        "42d294c1a 43a8f4537 ec9981703 9d23e9fea a5e63c741 b590555a7 af5cc76d0 36f6807be "
        "d9e7509ba 08e7485e6 ca410c173 34c0efac9 aa8dd95f8 92ff8e340 2fcf617e5 f4ee3deea "
        "ec3675f06 11d3034cc 53d80da67 2ffd3e2ed 701c5dbca fd41bd301 176d0d999 84a7a607a "
        "3a4cd4f6e 29fd854f3 239143be4 c1d83b7ce 3998e35f9 c9cade2fe 67a7ce5f8 58096eb5e "
        "129003b1a 58cd60dd3 7ec9c978c 8209b7fc6 b1a07b065 2f8c5d980 ec68f5262 9f6738ae8 "
        "e240da32d 29a692dd3 93a2fc212 90a7ad415 38462d719 88d09ed64 629414143 f37f54627 "
        "f654223da 9866d0462 39b7e344b e29b0d31e 4d26f996b ca999e2d4 48244ceca db430a091 "
        "b20a09f71 89d7a977d d0c7d781f 45dbd608b 5f0eaf573 4b72a881e 6721d71ac aea5b5257 "
        "729da786e b7bbb055e 33c26e035 bbb1faaf3 a7acc30bc 1ce0841a4 244d1d408 cde684816 "
        "0f8fb4cda 706c97e43 c971d3afb fda0d9c09 016b86da3 fad3fd2e5 bac1633c9 2309feea7 "
        "0033737bb 9aed89097 68538abb5 828f7850d 72432d95d 261a8e5a9 a200eb1b2 c3de7f043 "
        "bf74c5970 6dd1481b8 aa94bbef6 da7e65697 bc3ab5693 fac70dbec 11c7b546d f2f1877ae "
        "ddfd559cb 213843237 d35629a71 66b966ff8 f7c3d2b42 d2a9bf013 82aade491 80a74d66a "
        "c23180cd5 13bc699af 568f373af 4e8f6cb22 0236593da c06d419da fb63c9338 c58ea0e62 "
        "3f129af28 1bc5d8e7c 5a0cce5a2 12138fcc9 6475b47b3 36127061c a66ea1c90 c7622d06f "
        "7b06f9883 17f9dd0f5 4f7d20a59 80ca1778d 34bf99f09 b1f6b20ff ddc248171 79adedf2d "
        "e7b8ec414 1660b1a2a 596131143 ed5876f22 ccf196212 5a7da3ed3 5d7c1c564 ebf3b80d4 "
        "0fbb5da08 751b26b7f f646e15e0 48cf268f5 681ff913e 8a60709ee ee8aa3c19 d74c7190b "
        "403a516f6 43859f5e7 674b05601 29dc78f7b f871a0d9c 149cd7e80 e0ebb3dad cfd60dc21 "
        "fcac192f3 da0bb9f49 377891815 8cf831888 d8ad9cff2 66ef37c63 289532c5d 45d8a5400 "
        "452111b4d be9b62af0 4a7fa60af f38ab400e 329b05789 5edba3023 5f48632e5 c44562244 "
        "781f865e7 4868de42d b7d2aafdd 0652863c6 9c8c0a919 a566fd21e d42a60c7a 3b2fa8afe "
        "4feead808 4e08205a5 2ca3d8a2f 983fc5a57 c23db45c9 a37e0ba04 5f510ba05 1601a2ff1 "
        "30cccbfe0 3880f5176 0ea5aee4f b1b166fdb 7b3ca3761 64fae3ebf 447b9e7ac d9f564f30"
    ),
)

_TAG36H11 = AprilTagFamily(
    name="tag36h11",
    n_bits=36,
    min_hamming=11,
    width_at_border=8,
    bit_x=(
        1,
        2,
        3,
        4,
        5,
        2,
        3,
        4,
        3,
        6,
        6,
        6,
        6,
        6,
        5,
        5,
        5,
        4,
        6,
        5,
        4,
        3,
        2,
        5,
        4,
        3,
        4,
        1,
        1,
        1,
        1,
        1,
        2,
        2,
        2,
        3,
    ),
    bit_y=(
        1,
        1,
        1,
        1,
        1,
        2,
        2,
        2,
        3,
        1,
        2,
        3,
        4,
        5,
        2,
        3,
        4,
        3,
        6,
        6,
        6,
        6,
        6,
        5,
        5,
        5,
        4,
        6,
        5,
        4,
        3,
        2,
        5,
        4,
        3,
        4,
    ),
    codes_hex=(
        "d7e00984b dda664ca7 dc4a1c821 e17b470e9 ef91d01b1 f429cdd73 05da29225 1106cba43 "
        "223bed79d 21f51213c 33eb19ca6 3f76eb0f8 469a97414 45dcfe0b0 4a6465f72 51801db96 "
        "5eb946b4e 68a7cc2ec 6f0ba2652 78765559d 87b83d129 86cc4a5c5 8b64df90f 9c577b611 "
        "a3810f2f5 af4d75b83 b59a03fef bb1096f85 d1b92fc76 d0dd509d2 e2cfda160 2ff497c63 "
        "47240671b 5047a2e55 635ca87c7 691254166 68f43d94a 6ef24bdb6 8cdd8f886 9de96b718 "
        "aff6e5a8a bae46f029 d225b6d59 df8ba8c01 e3744a22f fbb59375d 18a916828 22f29c1ba "
        "286887d58 41392322e 75d18ecd1 87c302743 8c6317ba9 9e40f36d7 c0e5a806a cc78cb87c "
        "12d2f2d01 379f36a21 6973f59ac 7789ea9f4 8f1c73e84 8dd287a20 94a4eee4c a455379b5 "
        "a9e92987d bd25cb40b be98d3582 d3d5972b2 14c53d7c7 4f1796936 4e71fed1a 66d46fae0 "
        "a55abb933 ebee1acca 1ad4ba6a4 305b17571 553611351 59ca62775 7819cb6a1 edb7bc9eb "
        "5b2694212 72e12d185 ed6152e2c 5bcdadbf3 78e0aa0c6 c60a0b909 ef9a34b0d 398a6621a "
        "a8a27c944 4b564304e 52902b4e2 857280b56 a91b2c84b e91df939b 1fa405f28 23793ab86 "
        "68c17729f 9fbf3b840 36922413c 4eb5f946e 533fe2404 63de7d35e 925eddc72 99b8b3896 "
        "aace4c708 c22994af0 8f1eae41b d95fb486c 13fb77857 4fe0983a3 d559bf8a9 e1855d78d "
        "fec8daaad 71ecb6d95 dc9e50e4c ca3a4c259 740d12bbf aeedd18e0 b509b9c8e 5232fea1c "
        "19282d18b 76c22d67b 936beb34b 08a5ea8dd 679eadc28 a08e119c5 20a6e3e24 7eab9c239 "
        "96632c32e 470d06e44 8a70212fb 0a7e4251b 9ec762cc0 d8a3a1f48 db680f346 4a1e93a9d "
        "638ddc04f 4c2fcc993 01ef28c95 bf0d9792d 6d27557c3 623f977f4 35b43be57 bb0c428d5 "
        "a6f01474d 5a70c9749 20ddabc3b 2eabd78cf 90aa18f88 a9ea89350 3cdb39b22 839a08f34 "
        "169bb814e 1a575ab08 a04d3d5a2 bf7902f2b 095a5e65c 92e8fce94 67ef48d12 6400dbcac "
        "b12d8fb9f 0347f45d3 b35826f56 c546ac6e4 81cc35b66 41d14bd57 0c052b168 7d6ce5018 "
        "ab4ed5ede 5af817119 d1454b182 2badb090b 03fcb4c0c 2f1c28fd8 93608c6f7 4c93ba2b5 "
        "07d950a5d e54b3d3fc 15560cf9d 189e4958a 62140e9d2 723bc1cdb 2063f26fa fa08ab19f "
        "7955641db 646b01daa 71cd427cc 09a42f7d4 717edc643 15eb94367 8392e6bb2 832408542 "
        "2b9b874be b21f4730d b5d8f24c9 7dbaf6931 1b4e33629 13452e710 e974af612 1df61d29a "
        "99f2532ad e50ec71b4 5df0a36e8 4934e4cea e34a0b4bd b7b26b588 0f255118d d0c8fa31e "
        "06a50c94f f28aa9f06 131d194d8 622e3da79 ac7478303 c8f2521d7 6c9c881f5 49e38b60a "
        "513d8df65 d7c2b0785 9f6f9d75a 9f6966020 1e1a54e33 c04d63419 946e04cd7 1bdac5902 "
        "56469b830 ffad59569 86970e7d8 8a4b41e12 ad4688e3b 85f8f5df4 d833a0893 2a36fdd7c "
        "d6a857cf2 8829bc35c 5e50d79bc fbb8035e4 c1a95bebf 036b0baf8 e0da964ea b6483689b "
        "7c8e2f4c1 5b856a23b 2fc183995 e914b6d70 b31041969 1bb478493 063e2b456 f2a082b9c "
        "8e5e646ea 08172f8f6 0dacd923e e5dcf0e2e bf9446bae 4822d50d1 26e710bf5 b90ba2a24 "
        "f3b25aa73 809ad589b 94cc1e254 5334a3adb 592886b2f bf64704aa 566dbf24c 72203e692 "
        "64e61e809 d7259aad6 7b924aedc 2df2184e8 353d1eca7 fce30d7ce f7b0f436e 57e8d8f68 "
        "8c79e60db 9c8362b2b 63a5804f2 9298353dc 6f98a71c8 a5731f693 21ca5c870 1c2107fd3 "
        "6181f6c39 19e574304 329937606 043d5c70d 9b18ff162 8e2ccfebf 72b7b9b54 9b71f4f3c "
        "935d7393e 65938881a 6a5bd6f2d a19783306 e6472f4d7 81163df5a a838e1cbd 982748477 "
        "050c54feb 0d82fbb58 2c4c72799 97d259ad6 22d9a43ed fdb162a9f 0cb4a727d 4fae2e371 "
        "535b5be8b 48795908a ce7c18962 4ea154d80 50c064889 8d97fc75d c8bd9ec61 83ee8e8bb "
        "c8431419a 1aa78079d 8111aa4a5 dfa3a69fe 51630d83f 2d930fb3f 2133116e5 ae5395522 "
        "bc07a4e8a 57bf08ba0 6cb18036a f0e2e4b75 3eb692b6f d8178a3fa 238cce6a6 e97d5cdd7 "
        "fe10d8d5e b39584a1d ca03536fd aa61f3998 72ff23ec2 15aa7d770 57a3a1282 d1f3902dc "
        "6554c9388 fd01283c7 e8baa42c5 72cee6adf f6614b3fa 95c3778a2 7da4cea7a d18a5912c "
        "d116426e5 27c17bc1c b95b53bc1 c8f937a05 ed220c9bd 0c97d72ab 8fb1217ae 25ca8a5a1 "
        "b261b871b 1bef0a056 806a51179 eed249145 3f82aeceb cc56e9acf 2e78d01eb 102cee17f "
        "37caad3d5 16ac5b1ee 2af164ece d4cd81dc9 12263a7e7 57ac7d117 9391d9740 7aedaa77f "
        "9675a3c72 277f25191 ebb6e64b9 7ad3ef747 12759b181 948257d4d b63a850f6 3a52a8f75 "
        "4a019532c a021a7529 cc661876d 4085afd05 e7048e089 3f979cdc6 d9da9071b ed2fc5b68 "
        "79d64c3a1 fd44e2361 8eea46a74 42233b9c2 ae4d1765d 7303a094c 2d7033abe 3dcc2b0b4 "
        "0f0967d09 06f0cd7de 09807aca0 3a295cad3 2b106b202 3f38a828e 78af46596 bda2dc713 "
        "9a8c8c9d9 6a0f2ddce a76af6fe2 086f66fa4 d52d63f8d 89f7a6e73 cc6b23362 b4ebf3c39 "
        "564f300fa e8de3a706 79a033b61 765e160c5 a266a4f85 a68c38c24 dca0711fb 85fba85ba "
        "37a207b46 158fcc4d0 0569d79b3 7b1a25555 a8ae22468 7c592bdfd 0c59a5f66 b1115daa3 "
        "f17c87177 6769d766b 2b637356d 13d8685ac f24cb6ec0 0bd0b56d1 42ff0e26d b41609267 "
        "96f9518af c56f96636 4a8e10349 863512171 ea455d86c bd0e25279 e65e3f761 36c84a922 "
        "85fd1b38f 657c91539 15033fe04 09051c921 ab27d80d8 f92f7d0a1 8eb6bb737 10b5b0f63 "
        "6c9c7ad63 f66fe70ae ca579bd92 956198e4d 29e4405e5 e44eb885c 41612456c ea45e0abf "
        "d326529bd 7b2c33cef 80bc9b558 7169b9740 c37f99209 31ff6dab9 c795190ed a7636e95f "
        "9df075841 55a083932 a7cbdf630 409ea4ef0 92a1991b6 4b078dee9 ae18ce9e4 5a6e1ef35 "
        "1a403bd59 31ea70a83 2bc3c4f3a 5c921b3cb 042da05c5 1f667d16b 416a368cf fbc0a7a3b "
        "9419f0c7c 81be2fa03 34e2c172f 28648d8ae c7acbb885 45f31eb6a d1cfc0a7b 42c4d260d "
        "cf6584097 94b132b14 3c5c5df75 8ae596fef aea8054eb 0ae9cc573 496fb731b ebf105662 "
        "af9c83a37 c0d64cd6b 7b608159a e74431642 d6fb9d900 291e99de0 10500ba9a 5cd05d037 "
        "a87254fb2 9d7824a37 8b2c7b47c 30c788145 2f4e5a8be badb884da 026e0d5c9 6fdbaa32e "
        "34758eb31 565cd1b4f 2bfd90fb0 093052a6b d3c13c4b9 2daea43bf a279762bc f1bd9f22c "
        "4b7fec94f 545761d5a 7327df411 1b52a442e 49b0ce108 24c764bc8 374563045 a3e8f91c6 "
        "0e6bd2241 e0e52ee3c 07e8e3caa 96c2b7372 33acbdfda b15d91e54 464759ac1 6886a1998 "
        "57f5d3958 5a1f5c1f5 0b58158ad e712053fb 5352ddb25 414b98ea0 74f89f546 38a56b3c3 "
        "38db0dc17 aa016a755 dc72366f5 0cee93d75 b2fe7a56b a847ed390 8713ef88c a217cc861 "
        "8bca25d7b 455526818 ea3a7a180 a9536e5e0 9b64a1975 5bfc756bc 046aa169b 53a17f76f "
        "4d6815274 cca9cf3f6 4013fcb8b 3d26cdfa5 5786231f7 7d4ab09ab 960b5ffbc 8914df0d4 "
        "2fc6f2213 ac235637e 151b28ed3 46f79b6db 1382e0c9f 53abf983a 383c47ade 3fcf88978 "
        "eb9079df7 09af0714d da19d1bb7 9a02749f8 1c62dab9b 1a137e44b 2867718c7 35815525b "
        "7cd35c550 2164f73a0 e8b772fe0"
    ),
)


FAMILIES: dict[str, AprilTagFamily] = {
    "tag16h5": _TAG16H5,
    "tag25h9": _TAG25H9,
    "tag36h10": _TAG36H10,
    "tag36h11": _TAG36H11,
}
"""The families by name."""
